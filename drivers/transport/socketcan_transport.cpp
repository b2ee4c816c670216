#include "drivers/transport/socketcan_transport.hpp"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/experimental/awaitable_operators.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace fieldgate {

using namespace boost::asio::experimental::awaitable_operators;
using canopen::CanFrame;

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
constexpr std::size_t kMaxBatch = 64;  // frames per receive, so senders get a turn

std::error_code last_error() {
  return {errno, std::generic_category()};
}
}  // namespace

SocketCanTransport::SocketCanTransport(asio::any_io_executor executor, std::string interface)
    : executor_(executor), interface_(std::move(interface)), descriptor_(executor) {}

SocketCanTransport::~SocketCanTransport() {
  close();
}

std::error_code SocketCanTransport::open(const std::vector<uint32_t>& cob_ids) {
  close();
  const unsigned index = ::if_nametoindex(interface_.c_str());
  if (index == 0) return std::make_error_code(std::errc::no_such_device);
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) return last_error();
  const auto fail = [fd]() {
    const auto ec = last_error();
    ::close(fd);
    return ec;
  };
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, interface_.c_str(), IFNAMSIZ - 1);
  if (::ioctl(fd, SIOCGIFFLAGS, &ifr) < 0) return fail();
  if (!(ifr.ifr_flags & IFF_UP)) {
    ::close(fd);
    return std::make_error_code(std::errc::network_down);
  }
  std::vector<can_filter> filters;
  for (const auto id : cob_ids) filters.push_back({id, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG});
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                   static_cast<socklen_t>(filters.size() * sizeof(can_filter))) < 0)
    return fail();
  const can_err_mask_t errors = CAN_ERR_MASK;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof errors) < 0) return fail();
  const int on = 1;
  if (::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) < 0) return fail();
  const int sndbuf = 0;
  if (::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof sndbuf) < 0) return fail();
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(index);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) return fail();
  boost::system::error_code ec;
  descriptor_.assign(fd, ec);
  if (ec) {
    ::close(fd);
    return {ec.value(), std::generic_category()};
  }
  return {};
}

void SocketCanTransport::close() {
  if (!descriptor_.is_open()) return;
  boost::system::error_code ignored;
  descriptor_.close(ignored);
}

bool SocketCanTransport::drain(std::vector<CanFrame>& frames, std::error_code& ec) {
  const int fd = descriptor_.native_handle();
  for (std::size_t n = 0; n < kMaxBatch; ++n) {
    can_frame raw{};
    iovec iov{&raw, sizeof raw};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(uint32_t))];
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    const ssize_t got = ::recvmsg(fd, &msg, MSG_DONTWAIT);
    if (got < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
      ec = last_error();  // ENETDOWN, ENODEV: the interface went down or away
      return false;
    }
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c))
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
        uint32_t dropped = 0;
        std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
        stats_.rx_dropped = std::max<uint64_t>(stats_.rx_dropped, dropped);
      }
    if (static_cast<std::size_t>(got) != sizeof raw || (raw.can_id & CAN_EFF_FLAG)) continue;
    CanFrame f;
    f.error = raw.can_id & CAN_ERR_FLAG;
    f.rtr = !f.error && (raw.can_id & CAN_RTR_FLAG);
    f.id = f.error ? (raw.can_id & CAN_ERR_MASK) : (raw.can_id & CAN_SFF_MASK);
    f.len = std::min<uint8_t>(raw.len, 8);
    if (!f.rtr) std::memcpy(f.data.data(), raw.data, f.len);
    if (f.error)
      ++stats_.error_frames;
    else
      ++stats_.frames_received;
    frames.push_back(f);
  }
  return true;
}

asio::awaitable<std::error_code> SocketCanTransport::receive(std::vector<CanFrame>& frames) {
  for (;;) {
    if (!descriptor_.is_open()) co_return std::make_error_code(std::errc::bad_file_descriptor);
    std::error_code ec;
    if (!drain(frames, ec)) co_return ec;
    if (!frames.empty()) co_return std::error_code{};
    auto [wait_ec] =
        co_await descriptor_.async_wait(asio::posix::descriptor_base::wait_read, use_tuple);
    if (wait_ec) co_return std::error_code{wait_ec.value(), std::generic_category()};
  }
}

asio::awaitable<std::error_code> SocketCanTransport::send(const CanFrame& frame,
                                                          std::chrono::microseconds timeout) {
  can_frame raw{};
  raw.can_id = frame.id | (frame.rtr ? CAN_RTR_FLAG : 0u) | (frame.error ? CAN_ERR_FLAG : 0u);
  raw.len = frame.len;
  std::memcpy(raw.data, frame.data.data(), std::min<std::size_t>(frame.len, 8));
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (!descriptor_.is_open()) co_return std::make_error_code(std::errc::bad_file_descriptor);
    const ssize_t n = ::write(descriptor_.native_handle(), &raw, sizeof raw);
    if (n == static_cast<ssize_t>(sizeof raw)) {
      ++stats_.frames_sent;
      co_return std::error_code{};
    }
    if (n >= 0) co_return std::make_error_code(std::errc::message_size);
    if (errno == EINTR) continue;
    const int err = errno;
    if (err != EAGAIN && err != EWOULDBLOCK && err != ENOBUFS)
      co_return std::error_code{err, std::generic_category()};
    if (std::chrono::steady_clock::now() >= deadline)
      co_return std::make_error_code(std::errc::timed_out);
    asio::steady_timer timer(executor_);
    if (err == ENOBUFS) {
      // The driver queue is full and poll() would say writable at once: retry on a timer.
      timer.expires_after(std::chrono::milliseconds(1));
      co_await timer.async_wait(use_tuple);
    } else {
      timer.expires_at(deadline);
      co_await (descriptor_.async_wait(asio::posix::descriptor_base::wait_write, use_tuple) ||
                timer.async_wait(use_tuple));
    }
  }
}

}  // namespace fieldgate
