#pragma once

#include <cstdint>

namespace fieldgate {

// Fields of every node's diagnostics, as each front door shows them (the Modbus register map
// in this order from layout::diagnostics, Sparkplug as Diagnostics/ metrics).
enum class DiagnosticField {
  online,            // 1 while the node answers
  last_good_age_ms,  // uint32, 0xffffffff before the first good poll
  consecutive_timeouts,
  transactions,       // uint32
  timeouts,           // uint32
  errors,             // uint32 (device errors and garbled replies)
  last_device_error,  // 16 bits; 0xffff for a wider code (last_device_error_code has it)
  action_status,
  action_code,
  action_error,
  node_state,      // 0 starting, 1 online, 2 offline, 3 faulted
  unknown_writes,  // uint32: commands sent that got no valid reply (outcome unknown)
  data_age_ms,     // uint32: age of the oldest polled value, 0xffffffff if one was never read
  unreachable,     // uint32: a forwarding device said the node is not reachable (Copley e 32)
  // uint32: the last device error code in full (a CANopen SDO abort code has 32 bits). Last in
  // the block, so the fields before it keep their registers.
  last_device_error_code,
};

enum class ActionStatus : uint16_t { idle = 0, busy = 1, done = 2, error = 3 };

}  // namespace fieldgate
