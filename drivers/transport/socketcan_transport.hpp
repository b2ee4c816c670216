#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/awaitable.hpp>
#include <boost/asio/posix/stream_descriptor.hpp>
#include <boost/asio/steady_timer.hpp>

#include <linux/can.h>

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "drivers/transport/can_frame.hpp"

namespace fieldgate {

namespace asio = boost::asio;

struct CanChannelStats {
  uint64_t frames_sent = 0;
  uint64_t frames_received = 0;
  uint64_t error_frames = 0;
  uint64_t rx_dropped = 0;  // frames the kernel dropped because our receive queue was full
  uint64_t tx_dropped = 0;  // frames never sent: the transmit queue stayed full, or the link failed
};

// A CAN link as the CAN bus runtime uses it: frames in, frames out, error frames reported. Like
// Lely's io_can_chan, an interface so tests can put an in-memory bus behind it.
class CanChannel {
 public:
  virtual ~CanChannel() = default;
  // Opens the channel receiving data frames with exactly these identifiers, plus error frames.
  virtual std::error_code open(const std::vector<uint32_t>& cob_ids) = 0;
  virtual void close() = 0;
  virtual bool is_open() const = 0;
  // Waits until frames arrive and appends them; an error means the link failed (interface down
  // or gone) or the channel was closed. Cancellable by close().
  virtual asio::awaitable<std::error_code> receive(std::vector<CanFrame>& frames) = 0;
  // Sends one frame; frames that find no room in the transmit queue for `timeout` are dropped
  // (and counted). Several coroutines may send at the same time. An error means the link
  // failed.
  virtual asio::awaitable<std::error_code> send(const CanFrame& frame,
                                                std::chrono::microseconds timeout) = 0;
  virtual std::string describe() const = 0;
  virtual const CanChannelStats& stats() const = 0;
};

// A raw SocketCAN socket (AF_CAN, SOCK_RAW, CAN_RAW) bound to one interface, driven by the
// io_context through a posix::stream_descriptor. Receive filters match the given COB-IDs
// exactly (the kernel's fast path); error frames are enabled (CAN_RAW_ERR_FILTER) and kernel
// drops counted (SO_RXQ_OVFL). A minimal SO_SNDBUF turns a full transmit queue into EAGAIN,
// which the descriptor can wait on, instead of ENOBUFS. Frames are read with recvmmsg and
// written with sendmmsg: a burst of nodes costs one system call each way, which is what
// matters where system calls are slow (User-Mode Linux).
class SocketCanTransport final : public CanChannel {
 public:
  SocketCanTransport(asio::any_io_executor executor, std::string interface);
  ~SocketCanTransport() override;

  std::error_code open(const std::vector<uint32_t>& cob_ids) override;
  void close() override;
  bool is_open() const override { return descriptor_.is_open(); }
  asio::awaitable<std::error_code> receive(std::vector<CanFrame>& frames) override;
  asio::awaitable<std::error_code> send(const CanFrame& frame,
                                        std::chrono::microseconds timeout) override;
  std::string describe() const override { return "SocketCAN " + interface_; }
  const CanChannelStats& stats() const override { return stats_; }
  const std::string& interface() const { return interface_; }

 private:
  static constexpr std::size_t kMaxQueued = 1024;

  // Reads what the socket has without blocking; false with ec set when the link failed.
  bool drain(std::vector<CanFrame>& frames, std::error_code& ec);
  enum class Flush { done, blocked, no_buffers, failed };
  // Writes queued frames until the queue is empty or the socket has no room.
  Flush flush();
  // Flushes; when the socket has no room, wait_writable() goes on once it has.
  void start_flush();
  asio::awaitable<void> wait_writable(bool no_buffers, std::shared_ptr<bool> alive);

  asio::any_io_executor executor_;
  std::string interface_;
  asio::posix::stream_descriptor descriptor_;
  CanChannelStats stats_;
  std::deque<can_frame> tx_queue_;
  std::chrono::microseconds tx_timeout_{std::chrono::milliseconds(100)};
  std::error_code tx_error_;
  bool flush_posted_ = false;
  bool tx_waiting_ = false;
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);  // for handlers posted earlier
};

}  // namespace fieldgate
