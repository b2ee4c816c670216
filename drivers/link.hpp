#pragma once

#include <boost/asio/awaitable.hpp>
#include <boost/asio/steady_timer.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "drivers/transport/byte_transport.hpp"

namespace fieldgate {

struct LinkTiming {
  // To the first byte of a reply, counted from when the request has left the wire (its wire
  // time at the link's rate is added to the deadline).
  std::chrono::microseconds reply_timeout{std::chrono::milliseconds(100)};
  std::chrono::microseconds byte_timeout{std::chrono::milliseconds(20)};  // gap inside a reply
  // Quiet time the line must show before it carries anything after a timeout, a garbled or a
  // partial reply; 0 derives it (guard_time()).
  std::chrono::microseconds guard_time{0};
  // A forwarding device's own timeout on the network behind it (a Copley gateway amplifier
  // answers e 32 for an absent CAN node only after it); 0 = the family's default.
  std::chrono::microseconds forward_timeout{0};
};

// The resynchronisation guard: the configured one, or reply_timeout (a reply that was late by
// up to one more timeout starts inside the window) plus the larger of byte_timeout and 16
// character times (so the window outlasts a gap inside that late reply).
std::chrono::microseconds guard_time(const LinkTiming& timing, double char_time_us);

struct LinkStats {
  uint64_t bytes_sent = 0;
  uint64_t bytes_received = 0;
  uint64_t bytes_discarded = 0;  // stray input thrown away before a request or while resyncing
  uint64_t resyncs = 0;          // guard periods waited after a failed exchange
  uint64_t resync_bytes = 0;     // bytes that arrived during them (late or stray replies)
};

// What a resynchronisation found on the line.
struct LinkResync {
  std::string drained;  // everything that arrived (or was buffered) before the line went quiet
  bool quiet = true;    // false: the line never went quiet within the limit
  std::chrono::microseconds waited{0};
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
  // Clears our buffer and the OS input queue before a request; counts and traces what was
  // thrown away. What the OS holds is read off (so strays show in the trace); the transport's
  // flush follows unless the last read ended in a whole frame and nothing was left over.
  void discard_input();
  // Replies carry no tag, so after a timeout, a garbled or a partial reply the link may not
  // carry another request until it has been quiet for `guard` (from when our last byte left
  // the wire): whatever arrives meanwhile is the late part of an earlier exchange and is
  // drained. Gives up when the line is still busy after `limit`.
  asio::awaitable<LinkResync> resync(std::chrono::microseconds guard,
                                     std::chrono::microseconds limit);
  // Bytes received but not consumed by a frame (left over after the last reply).
  std::size_t buffered() const { return buffer_.size(); }
  std::string_view buffered_bytes() const { return buffer_; }
  // Waits without touching the line (inter-frame gap, pacing).
  asio::awaitable<void> pause(std::chrono::microseconds duration);

  // Sending ahead: the next exchange's request, written the moment the bus has accepted the
  // reply before it (the line proven in step), so the wire does not wait for the bookkeeping
  // between two exchanges. Written at once or not at all (false: the transport would have had
  // to wait, or cannot write without waiting). The exchange it belongs to takes it over: after
  // take_over_sent_ahead() its first send() must ask for exactly these bytes, and writes
  // nothing. Until then discard_input() and reads that may not wait leave the input alone:
  // whatever arrives is that request's reply. Another send() meanwhile (an urgent command)
  // goes out as it would have.
  bool send_ahead(std::string_view bytes);
  bool has_sent_ahead() const { return !ahead_.empty(); }
  std::chrono::steady_clock::time_point sent_ahead_at() const { return ahead_at_; }
  void take_over_sent_ahead() { taking_over_ = !ahead_.empty(); }
  // The bytes sent ahead are given up without their exchange (their reply is owed to the line).
  void drop_sent_ahead();
  // True once after a send() that should have taken over the bytes sent ahead asked for others
  // (it sent nothing and failed): the line owes the reply to the bytes sent ahead.
  bool take_ahead_mismatch() { return std::exchange(ahead_mismatch_, false); }

  // A line a family wants in the gateway's log, at a syslog level (4 warning, 5 notice, 6 info,
  // 7 debug). Every stream family logs this way: the bus logs the notes with its name and
  // clears them after each family call that may leave some (drivers/README.md).
  struct Note {
    int level = 5;
    std::string text;
  };
  void note(std::string text, int level = 5) { notes_.push_back({level, std::move(text)}); }
  std::vector<Note> take_notes() { return std::exchange(notes_, {}); }

  // Sees every byte the link sends (tx) and every frame, partial frame or drained run it
  // receives (rx), for the wire trace.
  using Tap = std::function<void(bool tx, std::string_view bytes)>;
  void set_tap(Tap tap) { tap_ = std::move(tap); }
  // For the tap: when the bytes it sees went out or came in. Now, but for a request sent ahead,
  // which the tap sees when its exchange takes it over: when it was written.
  std::chrono::steady_clock::time_point tap_time() const {
    return tap_at_ ? *tap_at_ : std::chrono::steady_clock::now();
  }
  // What a family knows of the frame it just sent or read, in the protocol's words (a protocol
  // file's command name; a reply's captures), for the wire trace line of that frame. Building
  // a label costs a format: families ask labels_wanted() first, which the bus sets while it
  // traces.
  using LabelTap = std::function<void(std::string_view label)>;
  void set_label_tap(LabelTap tap) { label_tap_ = std::move(tap); }
  void want_labels(bool on) { labels_wanted_ = on; }
  bool labels_wanted() const { return labels_wanted_ && label_tap_; }
  void label_last_frame(std::string_view label) {
    if (labels_wanted()) label_tap_(label);
  }

  ByteTransport& transport() { return transport_; }
  const LinkStats& stats() const { return stats_; }
  double char_time_us() const { return transport_.char_time_us(); }

 private:
  // When the bytes sent so far will have left the wire, estimated from the character time.
  std::chrono::steady_clock::time_point wire_free_at() const;
  // Counts n bytes the OS took and moves the estimate of when the line is free.
  void count_sent(std::size_t n);
  // The tap's view of bytes sent ahead, stamped with when they were written.
  void tap_sent_ahead(std::string_view bytes);
  // A read that ended without a frame: what had arrived goes with it (and to the trace).
  LinkRead end_read(LinkRead::Status status);
  // Appends what the OS already holds to `into` without waiting (one read), counted as
  // received; returns how many bytes came.
  std::size_t take_available(std::string& into);

  ByteTransport& transport_;
  std::size_t max_frame_;
  std::chrono::steady_clock::time_point tx_done_{};
  std::string buffer_;
  LinkStats stats_;
  std::vector<Note> notes_;
  Tap tap_;
  LabelTap label_tap_;
  bool labels_wanted_ = false;
  // The last read ended in a whole frame and no resync came after it. Then a flush before the
  // next request can only drop bytes that arrive while it runs, which a flush a moment earlier
  // would have missed as well: reading off the OS queue is enough.
  bool in_step_ = false;
  std::string ahead_;  // sent ahead, not yet taken over
  std::size_t ahead_written_ = 0;
  std::chrono::steady_clock::time_point ahead_at_{};
  bool taking_over_ = false;
  std::optional<std::chrono::steady_clock::time_point> tap_at_;
  bool ahead_mismatch_ = false;
};

}  // namespace fieldgate
