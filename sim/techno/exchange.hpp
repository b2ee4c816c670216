#pragma once

#include <deque>
#include <optional>
#include <random>
#include <string>
#include <string_view>

#include "sim/common/control_channel.hpp"
#include "sim/common/pty_port.hpp"
#include "sim/common/wire_pacing.hpp"
#include "sim/techno/controller.hpp"

namespace fieldgate::sim::techno {

struct ExchangeOptions {
  WireEmulation wire;
  std::uint32_t seed = 1;
  bool verbose = false;  // every line, raw byte and reply on stderr
};

// The I/O-free line side of a controller: CR-terminated lines (an LF after the CR is dropped),
// the raw STOP/RESET bytes wherever they arrive, wire timing both ways, injected faults, and
// replies the controller produces later (a capital move answers at its end). LineExchange in
// sim/common schedules every reply when its request is run, which a reply at the end of a motion
// that a STOP may cancel does not fit.
class TechnoExchange {
 public:
  TechnoExchange(Controller& controller, ExchangeOptions options, FaultInjection& faults);

  void receive(SimTime now, std::string_view bytes);
  // Runs what has arrived by `now` and appends the reply bytes due by `now`.
  void advance(SimTime now, std::string& out);
  std::optional<SimTime> next_deadline() const;

 private:
  struct Arrival {
    std::string bytes;  // a line without CR, or one raw byte
    bool raw = false;
    SimTime at;
  };

  void emit(SimTime at, std::string bytes);
  void log(SimTime now, std::string_view what, std::string_view bytes) const;

  Controller& controller_;
  ExchangeOptions options_;
  FaultInjection& faults_;
  std::string rx_;
  bool drop_lf_ = false;
  ReceiveWire receive_wire_;
  std::deque<Arrival> arrivals_;
  PacedTransmitter transmitter_;
  std::mt19937 random_;
  std::optional<SimTime> log_epoch_;
};

// Serves `exchange` on `port` and `control` until quit or SIGINT/SIGTERM/SIGHUP.
void run_techno_device(PtyPort& port, ControlChannel& control, TechnoExchange& exchange);

}  // namespace fieldgate::sim::techno
