#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <string_view>

namespace fieldgate::sim {

using SimClock = std::chrono::steady_clock;
using SimTime = SimClock::time_point;

enum class Parity { none, even, odd };

// Asynchronous character frame: start bit, data bits, optional parity bit, stop bits.
struct FrameFormat {
  unsigned data_bits = 8;
  Parity parity = Parity::none;
  unsigned stop_bits = 1;

  unsigned bits_per_character() const {
    return 1 + data_bits + (parity == Parity::none ? 0 : 1) + stop_bits;
  }
};

// Time a UART needs to shift characters at a baud rate.
class WireTiming {
 public:
  explicit WireTiming(std::uint32_t baud = 9600, FrameFormat format = {});

  std::uint32_t baud() const { return baud_; }
  void set_baud(std::uint32_t baud);
  const FrameFormat& format() const { return format_; }

  std::chrono::nanoseconds character_time() const { return wire_time(1); }
  // Computed for the whole count at once, so long transfers do not accumulate rounding.
  std::chrono::nanoseconds wire_time(std::size_t characters) const;

 private:
  std::uint32_t baud_;
  FrameFormat format_;
};

// What the simulator pretends about the line. With emulation off, requests count as complete
// when their last byte is read and replies go out in one write.
struct WireEmulation {
  bool enabled = false;
  WireTiming timing{};
  // Device processing time between the end of a request and the first reply bit.
  std::chrono::microseconds turnaround{0};
};

// The receive side of the line: a request cannot have arrived before its own bytes had time to
// cross the wire, counted from the moment its first byte was seen. Bytes read in one burst
// (a PTY delivers them instantly) queue behind each other as they would on a real line.
class ReceiveWire {
 public:
  // Call when the first byte of a request is read.
  void first_byte(SimTime seen);
  // The request has `characters` bytes (terminator included) and its last byte was read at
  // `read_at`; returns when it would have fully arrived. The next request starts from there.
  SimTime complete(std::size_t characters, SimTime read_at, const WireEmulation& wire);
  // When the request being received started: its first byte was seen, or the line was freed
  // by the request before it.
  SimTime started() const { return first_byte_; }

 private:
  SimTime first_byte_{};
  SimTime line_free_{};
};

// The transmit side: releases reply bytes at the instants their stop bits would leave a UART
// at the emulated rate. Bytes go out in chunks of about `granularity` of wire time, so the
// caller sleeps per chunk (poll timeout) instead of per byte; the schedule is computed from the
// transmission's start, so it is exact on average.
class PacedTransmitter {
 public:
  explicit PacedTransmitter(std::chrono::nanoseconds granularity = std::chrono::milliseconds(1))
      : granularity_(granularity) {}

  // Queues bytes to start leaving at `start`, or when the previous transmission has left,
  // whichever is later. timing == nullptr sends them all at the start instant.
  // Returns the instant the last byte will have left.
  SimTime enqueue(SimTime start, std::string_view bytes, const WireTiming* timing);

  // Appends every byte due by `now` to `out`.
  void release(SimTime now, std::string& out);

  std::optional<SimTime> next_due() const;
  bool idle() const { return chunks_.empty(); }
  // When the line is free for the next transmission.
  SimTime line_free() const { return line_free_; }

 private:
  struct Chunk {
    SimTime due;
    std::string bytes;
  };
  std::chrono::nanoseconds granularity_;
  std::deque<Chunk> chunks_;
  SimTime line_free_{};
};

}  // namespace fieldgate::sim
