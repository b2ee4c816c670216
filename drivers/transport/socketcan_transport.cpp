#include "drivers/transport/socketcan_transport.hpp"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/experimental/awaitable_operators.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <optional>

namespace fieldgate {

using namespace boost::asio::experimental::awaitable_operators;

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
  *alive_ = false;
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
  tx_queue_.clear();
  tx_error_.clear();
  if (!descriptor_.is_open()) return;
  boost::system::error_code ignored;
  descriptor_.close(ignored);
}

bool SocketCanTransport::drain(std::vector<CanFrame>& frames, std::error_code& ec) {
  // recvmmsg takes a burst (32 nodes answering at once) in one system call.
  constexpr std::size_t kBurst = 32;
  std::array<can_frame, kBurst> raw{};
  std::array<iovec, kBurst> iov{};
  std::array<mmsghdr, kBurst> msgs{};
  struct Control {
    alignas(cmsghdr) char bytes[CMSG_SPACE(sizeof(uint32_t))];
  };
  std::array<Control, kBurst> control{};
  const int fd = descriptor_.native_handle();
  for (std::size_t total = 0; total < kMaxBatch;) {
    for (std::size_t i = 0; i < kBurst; ++i) {
      iov[i] = {&raw[i], sizeof raw[i]};
      msgs[i] = {};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
      msgs[i].msg_hdr.msg_control = control[i].bytes;
      msgs[i].msg_hdr.msg_controllen = sizeof control[i].bytes;
    }
    const int got = ::recvmmsg(fd, msgs.data(), kBurst, MSG_DONTWAIT, nullptr);
    if (got < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
      ec = last_error();  // ENETDOWN, ENODEV: the interface went down or away
      return false;
    }
    for (int m = 0; m < got; ++m) {
      auto& msg = msgs[static_cast<std::size_t>(m)];
      const can_frame& r = raw[static_cast<std::size_t>(m)];
      for (cmsghdr* c = CMSG_FIRSTHDR(&msg.msg_hdr); c; c = CMSG_NXTHDR(&msg.msg_hdr, c))
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
          uint32_t dropped = 0;
          std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
          stats_.rx_dropped = std::max<uint64_t>(stats_.rx_dropped, dropped);
        }
      if (msg.msg_len != sizeof r || (r.can_id & CAN_EFF_FLAG)) continue;
      CanFrame f;
      f.error = r.can_id & CAN_ERR_FLAG;
      f.rtr = !f.error && (r.can_id & CAN_RTR_FLAG);
      f.id = f.error ? (r.can_id & CAN_ERR_MASK) : (r.can_id & CAN_SFF_MASK);
      f.len = std::min<uint8_t>(r.len, 8);
      if (!f.rtr) std::memcpy(f.data.data(), r.data, f.len);
      if (f.error)
        ++stats_.error_frames;
      else
        ++stats_.frames_received;
      frames.push_back(f);
    }
    total += static_cast<std::size_t>(got);
    if (static_cast<std::size_t>(got) < kBurst) return true;  // the queue is empty now
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
  if (!descriptor_.is_open()) co_return std::make_error_code(std::errc::bad_file_descriptor);
  if (tx_error_) co_return tx_error_;
  if (tx_queue_.size() >= kMaxQueued) {
    ++stats_.tx_dropped;
    co_return std::make_error_code(std::errc::timed_out);
  }
  can_frame raw{};
  raw.can_id = frame.id | (frame.rtr ? CAN_RTR_FLAG : 0u) | (frame.error ? CAN_ERR_FLAG : 0u);
  raw.len = frame.len;
  std::memcpy(raw.data, frame.data.data(), std::min<std::size_t>(frame.len, 8));
  tx_queue_.push_back(raw);
  tx_timeout_ = timeout;
  // Every frame queued by the handlers that run now goes out in one sendmmsg: after a burst of
  // answers each node's worker queues its next request, and they leave together.
  if (!flush_posted_ && !tx_waiting_) {
    flush_posted_ = true;
    asio::post(executor_, [this, alive = alive_] {
      if (!*alive) return;
      flush_posted_ = false;
      if (!tx_waiting_) start_flush();
    });
  }
  co_return std::error_code{};
}

SocketCanTransport::Flush SocketCanTransport::flush() {
  constexpr std::size_t kBurst = 64;
  std::array<can_frame, kBurst> raw{};
  std::array<iovec, kBurst> iov{};
  std::array<mmsghdr, kBurst> msgs{};
  while (!tx_queue_.empty()) {
    if (!descriptor_.is_open()) return Flush::failed;
    const std::size_t n = std::min(kBurst, tx_queue_.size());
    for (std::size_t i = 0; i < n; ++i) {
      raw[i] = tx_queue_[i];
      iov[i] = {&raw[i], sizeof raw[i]};
      msgs[i] = {};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    const int sent = ::sendmmsg(descriptor_.native_handle(), msgs.data(), static_cast<unsigned>(n),
                                MSG_DONTWAIT);
    if (sent > 0) {
      tx_queue_.erase(tx_queue_.begin(), tx_queue_.begin() + sent);
      stats_.frames_sent += static_cast<uint64_t>(sent);
      continue;
    }
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) return Flush::blocked;
    if (errno == ENOBUFS) return Flush::no_buffers;
    // ENETDOWN, ENODEV: the link failed; the reader sees it too.
    tx_error_ = last_error();
    stats_.tx_dropped += tx_queue_.size();
    tx_queue_.clear();
    return Flush::failed;
  }
  return Flush::done;
}

void SocketCanTransport::start_flush() {
  const auto r = flush();
  if (r != Flush::blocked && r != Flush::no_buffers) return;
  tx_waiting_ = true;
  asio::co_spawn(executor_, wait_writable(r == Flush::no_buffers, alive_), asio::detached);
}

asio::awaitable<void> SocketCanTransport::wait_writable(bool no_buffers,
                                                        std::shared_ptr<bool> alive) {
  auto deadline = std::chrono::steady_clock::now() + tx_timeout_;
  asio::steady_timer timer(executor_);
  for (;;) {
    if (no_buffers) {
      // The driver queue is full and poll() would say writable at once: retry on a timer.
      timer.expires_after(std::chrono::milliseconds(1));
      co_await timer.async_wait(use_tuple);
    } else {
      timer.expires_at(deadline);
      co_await (descriptor_.async_wait(asio::posix::descriptor_base::wait_write, use_tuple) ||
                timer.async_wait(use_tuple));
    }
    if (!*alive) co_return;
    const auto before = tx_queue_.size();
    const auto r = flush();
    if (r == Flush::done || r == Flush::failed) break;
    no_buffers = r == Flush::no_buffers;
    const auto now = std::chrono::steady_clock::now();
    if (tx_queue_.size() < before) {
      deadline = now + tx_timeout_;  // progress
    } else if (now >= deadline) {
      // Nothing went out for a whole timeout (a bus-off controller, nobody acknowledging): the
      // frames are stale, and the transfers waiting for them time out.
      stats_.tx_dropped += tx_queue_.size();
      tx_queue_.clear();
      break;
    }
  }
  tx_waiting_ = false;
}

}  // namespace fieldgate
