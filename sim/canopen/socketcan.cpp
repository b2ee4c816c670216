#include "socketcan.hpp"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <system_error>

namespace fieldgate::sim::canopen {

namespace {
[[noreturn]] void fail(const std::string& what) {
  throw std::system_error(errno, std::generic_category(), what);
}
constexpr std::size_t kMaxQueued = 4096;
}  // namespace

SocketCan::SocketCan(const std::string& interface, const std::vector<RxFilter>& filters)
    : interface_(interface) {
  fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0) fail("socket(PF_CAN, SOCK_RAW, CAN_RAW)");
  try {
    // Exact-match filters on standard data (or remote) frames: the kernel's fast path.
    std::vector<can_filter> kf;
    for (const auto& f : filters)
      kf.push_back(
          {f.id | (f.rtr ? CAN_RTR_FLAG : 0u), CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG});
    if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, kf.data(),
                     static_cast<socklen_t>(kf.size() * sizeof(can_filter))) < 0)
      fail("setsockopt(CAN_RAW_FILTER)");
    // A full transmit queue then reports EAGAIN instead of ENOBUFS, so poll() can wait for it.
    int sndbuf = 0;
    if (::setsockopt(fd_, SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof sndbuf) < 0)
      fail("setsockopt(SO_SNDBUF)");
    const unsigned index = ::if_nametoindex(interface.c_str());
    if (index == 0) fail("no CAN interface '" + interface + "'");
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(index);
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0)
      fail("bind to " + interface);
  } catch (...) {
    ::close(fd_);
    throw;
  }
}

SocketCan::~SocketCan() {
  if (fd_ >= 0) ::close(fd_);
}

std::optional<CanFrame> SocketCan::read() {
  for (;;) {
    can_frame raw{};
    const ssize_t n = ::read(fd_, &raw, sizeof raw);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return std::nullopt;
      if (errno == ENETDOWN) {
        ++down_events_;
        return std::nullopt;
      }
      fail("read from " + interface_);
    }
    if (n != sizeof raw) continue;
    if (raw.can_id & (CAN_EFF_FLAG | CAN_ERR_FLAG)) continue;
    CanFrame frame;
    frame.id = raw.can_id & CAN_SFF_MASK;
    frame.rtr = raw.can_id & CAN_RTR_FLAG;
    frame.len = std::min<std::uint8_t>(raw.len, 8);
    if (!frame.rtr) std::memcpy(frame.data.data(), raw.data, frame.len);
    return frame;
  }
}

void SocketCan::write(const CanFrame& frame) {
  if (queue_.size() >= kMaxQueued) {
    queue_.pop_front();
    ++dropped_;
  }
  queue_.push_back(frame);
  flush();
}

void SocketCan::flush() {
  enobufs_ = false;
  while (!queue_.empty()) {
    const CanFrame& frame = queue_.front();
    can_frame raw{};
    raw.can_id = frame.id | (frame.rtr ? CAN_RTR_FLAG : 0u);
    raw.len = frame.len;
    std::memcpy(raw.data, frame.data.data(), frame.len);
    const ssize_t n = ::write(fd_, &raw, sizeof raw);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return;
      if (errno == ENOBUFS) {
        enobufs_ = true;
        return;
      }
      if (errno == ENETDOWN) {  // interface down: the frame is lost, as on a real bus
        queue_.pop_front();
        ++dropped_;
        continue;
      }
      fail("write to " + interface_);
    }
    queue_.pop_front();
  }
}

}  // namespace fieldgate::sim::canopen
