// A non-blocking CAN_RAW socket bound to one interface, receiving only the given COB-IDs.
#pragma once

#include "can_frame.hpp"

#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

namespace fieldgate::sim::canopen {

struct RxFilter {
  std::uint32_t id;
  bool rtr;
};

class SocketCan {
 public:
  // Throws std::system_error naming the step that failed.
  SocketCan(const std::string& interface, const std::vector<RxFilter>& filters);
  ~SocketCan();
  SocketCan(const SocketCan&) = delete;
  SocketCan& operator=(const SocketCan&) = delete;

  int fd() const { return fd_; }
  // Next received frame, or nullopt when none is waiting.
  std::optional<CanFrame> read();
  // Queues a frame and writes what the kernel takes now; the rest waits for flush().
  void write(const CanFrame& frame);
  void flush();
  bool pending() const { return !queue_.empty(); }
  // After ENOBUFS (driver queue full) poll() says writable at once; retry on a timer instead.
  bool poll_for_writable() const { return !enobufs_; }
  std::uint64_t dropped() const { return dropped_; }
  // Times a read found the interface down (ENETDOWN); the socket keeps working once it is up.
  std::uint64_t down_events() const { return down_events_; }

 private:
  int fd_ = -1;
  std::string interface_;
  std::deque<CanFrame> queue_;
  std::uint64_t dropped_ = 0;
  std::uint64_t down_events_ = 0;
  bool enobufs_ = false;
};

}  // namespace fieldgate::sim::canopen
