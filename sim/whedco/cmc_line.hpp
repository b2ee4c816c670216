#pragma once

#include <chrono>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sim/common/line_device_loop.hpp"
#include "sim/whedco/cmc_unit.hpp"

namespace fieldgate::sim::whedco {

// How a unit lays out what it prints before the `*` prompt (the excerpt does not say; the
// family accepts both).
enum class ReplyStyle {
  compact,   // "1250\r\n*", "*"
  terminal,  // "\r\n 1250\r\n*", "\r\n*": every reply on a fresh line, numbers with a sign column
  // The reply on the echo's line: the CR that ends the request is not echoed, the value follows
  // after a space ("4RPX 1250\r\n*"); an acknowledge ends the line ("4AMX10\r\n*").
  inline_echo,
};

struct LineOptions {
  std::vector<UnitOptions> units;
  ReplyStyle style = ReplyStyle::compact;
  // Position reads take 5-10 ms on the real controller (A.2), on top of the turnaround.
  std::chrono::microseconds position_read_delay{0};
};

// Several CMC-0s on one RS-422/485 line: each line starts with a unit's address digit; only
// that unit echoes (in echo mode) and answers.
class CmcLine {
 public:
  CmcLine(LineOptions options, SimTime now);

  // Requests end at CR.
  static std::size_t frame(std::string_view pending);
  DeviceReply handle(std::string_view request, SimTime now);
  // Echo of the characters as they arrive: only an addressed, online unit in echo mode echoes,
  // and it sends CR LF for the CR.
  std::string echo(std::string_view received);

  // Family verbs of the control channel (see control_help()).
  std::optional<std::string> control(std::string_view verb, std::span<const std::string> arguments,
                                     SimTime now);
  static std::string control_help();

  CmcUnit* unit(int address);

 private:
  LineOptions options_;
  std::map<int, CmcUnit> units_;
  bool line_start_ = true;
  bool echoing_ = false;
};

// CLI helpers: "4,5" -> addresses; "WXYZ" or "4:XY,5:WXYZ" -> axes per unit; "all" or "4,5"
// -> which units are non-echo; "X" or "4:X" -> stepper axes. Throw std::invalid_argument.
std::vector<UnitOptions> parse_units(std::string_view addresses, std::string_view axes,
                                     std::string_view non_echo, std::string_view steppers);

}  // namespace fieldgate::sim::whedco
