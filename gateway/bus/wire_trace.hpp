#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate {

enum class TraceDirection { tx, rx };

// A token bucket: `rate` lines per second on average, bursts of up to `burst`.
class TokenBucket {
 public:
  using Clock = std::chrono::steady_clock;
  TokenBucket(double rate, double burst);
  bool take(Clock::time_point now);

 private:
  double rate_;
  double burst_;
  double tokens_;
  Clock::time_point last_{};
  bool started_ = false;
};

// One trace line, candump-like and grep-able (six fields, then the quoted bytes, then what the
// family said the frame was, if it said):
//   trace BUS (SECONDS.MICROS) NODE tx|rx OUTCOME 'BYTES' [LABEL]
// SECONDS is CLOCK_MONOTONIC (steady_clock); BYTES are already escaped (printable_bytes, which
// escapes the quote, or candump's ID#DATA on CAN), so the bytes end at the next quote. LABEL
// is a protocol file's command name, and on a reply its captures (`read_state e=0000 s=33`).
std::string format_trace_line(std::string_view bus, std::chrono::steady_clock::time_point at,
                              std::string_view node, TraceDirection direction,
                              std::string_view outcome, std::string_view bytes,
                              std::string_view label = {});

// The wire trace of one bus: off unless the config says `trace: true` or it is switched on at
// run time (SIGUSR2, POST /trace on the metrics endpoint). Lines go to the log (stderr, so
// journald) under the subject "trace", rate limited per bus; dropped lines are counted and
// reported in the next line that gets through.
// The run-time switch on the metrics endpoint: "POST /trace?bus=NAME&on=1" (or on=0) switches
// a bus, "POST /trace?on=1" every bus. Returns the HTTP status and a one-line body per bus.
struct TraceControlResult {
  int status = 200;
  std::string body;
};
TraceControlResult trace_control(std::string_view target);

// One frame as a live viewer (the web console) takes it, whether the log trace is on or not.
struct TraceFrame {
  std::string_view bus;
  std::chrono::steady_clock::time_point at;
  std::string_view node;
  TraceDirection direction;
  std::string_view outcome;
  std::string_view bytes;
  std::string_view label;
};

class WireTrace {
 public:
  using Sink = std::function<void(std::string_view line)>;
  using Observer = std::function<void(const TraceFrame& frame)>;
  static constexpr double kDefaultRate = 200;   // lines per second
  static constexpr double kDefaultBurst = 400;  // one poll cycle of a long chain

  explicit WireTrace(std::string bus, bool enabled = false, double rate = kDefaultRate,
                     double burst = kDefaultBurst);
  ~WireTrace();
  WireTrace(const WireTrace&) = delete;
  WireTrace& operator=(const WireTrace&) = delete;

  const std::string& bus() const { return bus_; }
  bool enabled() const { return enabled_; }
  // Whether frames are wanted at all: the log trace is on, or an observer watches.
  bool active() const { return enabled_ || observed(); }
  static bool observed();
  void set_enabled(bool on);
  void emit(std::chrono::steady_clock::time_point at, std::string_view node,
            TraceDirection direction, std::string_view outcome, std::string_view bytes,
            std::string_view label = {});
  uint64_t lines() const { return lines_; }
  uint64_t dropped() const { return dropped_; }

  // Where every trace writes; the log by default (tests capture it).
  static void set_sink(Sink sink);
  // Sees every frame of every bus, with no rate limit, while set (empty: none). Set only while
  // someone watches: each frame then costs a call.
  static void set_observer(Observer observer);
  // Every live trace (one per running bus), for the run-time switches.
  static std::vector<WireTrace*> all();
  // Switches the named bus's trace (a reload may briefly hold two); returns how many matched.
  static int set(std::string_view bus, bool on);
  // SIGUSR2: all on if any is off, else all off. Returns the new state.
  static bool toggle_all();

 private:
  void write(std::string_view line);

  std::string bus_;
  bool enabled_;
  TokenBucket bucket_;
  uint64_t lines_ = 0;
  uint64_t dropped_ = 0;
  uint64_t unreported_ = 0;
};

}  // namespace fieldgate
