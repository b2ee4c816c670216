#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <string_view>

#include "sim/common/control_channel.hpp"
#include "sim/common/pty_port.hpp"
#include "sim/common/wire_pacing.hpp"

namespace fieldgate::sim {

// What a device answers to one request.
struct DeviceReply {
  std::string bytes;  // empty: the device stays silent (e.g. Copley's reset)
  // The link changes rate before the reply leaves (Copley answers a baud change at the new rate).
  std::optional<std::uint32_t> new_baud;
  // Device latency on top of the turnaround, e.g. forwarding to another node.
  std::chrono::microseconds extra_delay{0};
};

// How a family turns the byte stream into requests and requests into replies.
struct LineDeviceHooks {
  // Length of the complete request at the front of `pending`, terminator included; 0 while more
  // bytes are needed. The family decides (CR for Copley, LF for IMS party line, …).
  std::function<std::size_t(std::string_view pending)> frame;
  // Executes one request at `now` and returns the reply.
  std::function<DeviceReply(std::string_view request, SimTime now)> respond;
  // Optional: bytes a device echoes as characters arrive (IMS, Whedco echo mode).
  std::function<std::string(std::string_view received)> echo;
  // Optional: bytes that act alone wherever they arrive, even inside a request, and take no wire
  // time of their own (Techno's STOP 0xFF and RESET 0xFE). `raw` runs each in order with the
  // requests around it; they never reach `frame`.
  std::string raw_bytes;
  std::function<DeviceReply(char byte, SimTime now)> raw;
  // Optional, for a device that answers on its own timeline (Techno: a capital move answers at
  // its end): runs it up to `now`, its replies going out through LineExchange::emit().
  std::function<void(SimTime now)> advance;
  // When `advance` next has something to do.
  std::function<std::optional<SimTime>()> next_event;
};

struct LineDeviceOptions {
  WireEmulation wire;
  // Stripped from the end of a reply before it is truncated.
  std::string terminators = "\r\n";
  // One of these bytes right after a complete request is dropped unheard and takes no wire time:
  // Techno's LF that may follow the CR.
  std::string dropped_after_request;
  // Unframed input beyond this is discarded, as an overflowing UART buffer would.
  std::size_t max_pending = 4096;
  std::uint32_t seed = 1;
  bool verbose = false;  // log every request and reply to stderr
  // Device journal: one line per executed request, "<µs since the first request> <request> ->
  // <reply as the device produced it> [<fault applied on the way out>]", flushed at once, so a
  // test can check what the device really did. nullptr: none.
  std::FILE* journal = nullptr;
  // Wire log, for benchmarks: one line per executed request, "<first byte> <arrived> <request
  // bytes> <echoed bytes> <reply bytes> <device delay µs> <request escaped>", the two instants in
  // ns on CLOCK_MONOTONIC (std::chrono::steady_clock), the reply as the device produced it and the
  // delay being the turnaround plus the device's own extra latency. nullptr: none.
  std::FILE* wire_log = nullptr;
  std::string name = "sim";
};

// The I/O-free core of a line-oriented device: frames requests, holds each until its bytes would
// have crossed the wire, runs it, applies injected faults and schedules the reply at wire speed.
// Time only moves when the caller passes it in, so tests need neither a PTY nor sleeps.
class LineExchange {
 public:
  LineExchange(LineDeviceHooks hooks, LineDeviceOptions options, FaultInjection& faults);

  // Bytes read from the host at `now`.
  void receive(SimTime now, std::string_view bytes);
  // Runs every request that has arrived by `now` (each at its arrival instant), then the device's
  // own timeline, and appends the reply bytes due by `now`.
  void advance(SimTime now, std::string& out);
  // A reply the device produces at `at` outside `respond` (LineDeviceHooks::advance): faults,
  // turnaround and wire time apply as to any reply. Journalled with an empty request.
  void emit(SimTime at, std::string_view bytes);
  // When advance() next has something to do.
  std::optional<SimTime> next_deadline() const;

  std::uint32_t baud() const { return options_.wire.timing.baud(); }
  // The device changed rate outside a reply (e.g. a reset injected from the control channel).
  void set_baud(std::uint32_t baud) { options_.wire.timing.set_baud(baud); }
  bool idle() const { return rx_.empty() && requests_.empty() && transmitter_.idle(); }

 private:
  struct PendingRequest {
    std::string bytes;
    SimTime arrived;
    SimTime started;         // its first byte on the wire
    std::size_t echoed = 0;  // bytes echoed while it arrived
    bool raw = false;        // one of LineDeviceHooks::raw_bytes
  };

  void take(SimTime now, std::string_view bytes);
  void take_raw(SimTime now, char byte);
  void execute(const PendingRequest& request, SimTime now);
  // Faults, journal and transmission of the reply `reply` to `request`.
  void send(SimTime now, std::string_view request, std::string_view reply,
            std::chrono::microseconds extra_delay);
  std::string garbage(std::string_view reply);
  std::string truncated(std::string_view reply) const;
  void journal(SimTime now, std::string_view request, std::string_view reply,
               std::string_view fault);
  void log(SimTime now, std::string_view what, std::string_view bytes) const;

  LineDeviceHooks hooks_;
  LineDeviceOptions options_;
  FaultInjection& faults_;
  std::string rx_;
  ReceiveWire receive_wire_;
  std::deque<PendingRequest> requests_;
  PacedTransmitter transmitter_;
  std::mt19937 random_;
  std::mt19937 chaos_random_;
  unsigned chaos_generation_ = 0;
  std::optional<SimTime> log_epoch_;
  std::size_t echoed_ = 0;      // echoed bytes of the request being received
  bool after_request_ = false;  // the last byte taken completed a request
};

// Serves `exchange` on `port` and `control` until the control channel says quit or SIGINT,
// SIGTERM or SIGHUP arrives. One thread, one poll() over the PTY master and stdin.
void run_line_device(PtyPort& port, ControlChannel& control, LineExchange& exchange);

// "g r0x32\r" -> "g r0x32\\r", for logs and test messages.
std::string escape_bytes(std::string_view bytes);

}  // namespace fieldgate::sim
