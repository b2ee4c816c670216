#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "sim/common/control_channel.hpp"
#include "sim/common/line_device_loop.hpp"
#include "sim/common/wire_pacing.hpp"
#include "sim/techno/controller.hpp"

namespace fieldgate::sim::techno {

// What a controller makes of the common line: CR-terminated lines, the raw STOP (0xFF) and RESET
// (0xFE) bytes wherever they arrive, and replies on the controller's own timeline (a capital move
// answers at its end), which reach the line through LineExchange::emit().
LineDeviceHooks line_hooks(Controller& controller);
// The line settings the protocol fixes: CR ends a line and an LF right after it is dropped (p.29).
void set_line_framing(LineDeviceOptions& options);

struct ExchangeOptions {
  WireEmulation wire;
  std::uint32_t seed = 1;
  bool verbose = false;  // every line, raw byte and reply on stderr
};

// A controller on an I/O-free LineExchange, for tests that drive it with injected time.
class TechnoExchange {
 public:
  TechnoExchange(Controller& controller, ExchangeOptions options, FaultInjection& faults);
  TechnoExchange(const TechnoExchange&) = delete;
  TechnoExchange& operator=(const TechnoExchange&) = delete;

  void receive(SimTime now, std::string_view bytes) { line_.receive(now, bytes); }
  // Runs what has arrived by `now` and appends the reply bytes due by `now`.
  void advance(SimTime now, std::string& out) { line_.advance(now, out); }
  std::optional<SimTime> next_deadline() const { return line_.next_deadline(); }

 private:
  LineExchange line_;
};

}  // namespace fieldgate::sim::techno
