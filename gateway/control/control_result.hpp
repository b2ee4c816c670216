#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "drivers/protocol_family.hpp"

namespace fieldgate {

// What became of a write or command, in the domain's terms. Each front door (Modbus TCP and RTU,
// the axis profile, Sparkplug) maps it to its own codes in one place.
enum class ControlStatus {
  ok,
  no_such_target,   // no writable point, setpoint or action by that number
  out_of_range,     // outside its type, the model's min/max or the site's `limits:`
  writes_disabled,  // the front door allows no such write (monitor-only, read-only)
  not_supported,    // the axis has no such command
  line_held,        // an action's step holds the node's line (a motion answered at its end)
  value_unknown,    // a value the command passes on was never read
  device_error,     // the device answered and refused; device_code has its code
  outcome_unknown,  // sent without a valid reply: it may have run
  unreachable,      // not sent: the node is offline, the line not in step, the link down
};

std::string_view to_string(ControlStatus status);

struct ControlResult {
  ControlStatus status = ControlStatus::ok;
  std::string detail;  // for people: what was refused and why, the device's own text
  int64_t device_code = 0;

  bool ok() const { return status == ControlStatus::ok; }
  static ControlResult success() { return {}; }
  static ControlResult of(ControlStatus status, std::string detail) {
    return {status, std::move(detail), 0};
  }
};

// How a bus reply to a sent write or action step ends it.
ControlResult control_result_of(const Reply& reply);

}  // namespace fieldgate
