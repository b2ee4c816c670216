#pragma once

#include <boost/asio/awaitable.hpp>
#include <boost/asio/steady_timer.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "drivers/transport/byte_transport.hpp"

namespace fieldgate {

struct LinkTiming {
  std::chrono::microseconds reply_timeout{std::chrono::milliseconds(100)};  // to the first byte
  std::chrono::microseconds byte_timeout{std::chrono::milliseconds(20)};    // gap inside a reply
};

struct LinkStats {
  uint64_t bytes_sent = 0;
  uint64_t bytes_received = 0;
  uint64_t bytes_discarded = 0;  // stray input thrown away before a request
};

// Returns the length of the complete frame at the start of the buffer, or 0 if more is needed.
using FrameSplitter = std::function<std::size_t(std::string_view)>;

struct LinkRead {
  enum class Status { frame, timeout, overflow, error };
  Status status = Status::timeout;
  std::string frame;    // the complete frame, terminator included
  std::string partial;  // what had arrived when a timeout or overflow ended the read
  std::error_code error;
};

// The request/reply primitive families build transactions from: sends bytes and reads framed
// replies with a first-byte and an inter-byte deadline. Bytes after a frame stay buffered for
// the next read of the same transaction.
class Link {
 public:
  explicit Link(ByteTransport& transport, std::size_t max_frame = 1024);

  asio::awaitable<std::error_code> send(std::string_view bytes);
  asio::awaitable<LinkRead> read_frame(const FrameSplitter& splitter, const LinkTiming& timing);
  // Clears our buffer and the OS input queue; counts what was thrown away.
  void discard_input();
  // Waits without touching the line (inter-frame gap, pacing).
  asio::awaitable<void> pause(std::chrono::microseconds duration);

  // Messages a family wants in the gateway's log (e.g. what a link-open procedure did); the
  // bus logs and clears them after each family call that may leave some.
  void note(std::string message) { notes_.push_back(std::move(message)); }
  std::vector<std::string> take_notes() { return std::exchange(notes_, {}); }

  ByteTransport& transport() { return transport_; }
  const LinkStats& stats() const { return stats_; }
  double char_time_us() const { return transport_.char_time_us(); }

 private:
  ByteTransport& transport_;
  std::size_t max_frame_;
  std::string buffer_;
  LinkStats stats_;
  std::vector<std::string> notes_;
};

}  // namespace fieldgate
