#include "gateway/register_map/control_exception.hpp"

namespace fieldgate {

modbus::ExceptionCode exception_for(ControlStatus status) {
  using modbus::ExceptionCode;
  switch (status) {
    case ControlStatus::ok:
      break;  // not an exception: callers answer success
    case ControlStatus::no_such_target:
      return ExceptionCode::illegal_data_address;
    case ControlStatus::out_of_range:
      return ExceptionCode::illegal_data_value;
    case ControlStatus::writes_disabled:
    case ControlStatus::not_supported:
      return ExceptionCode::illegal_function;
    case ControlStatus::line_held:
      // Answered at once rather than after the motion: a PLC would time out and repeat.
      return ExceptionCode::server_busy;
    case ControlStatus::device_error:
      return ExceptionCode::server_device_failure;
    case ControlStatus::value_unknown:
    case ControlStatus::outcome_unknown:
    case ControlStatus::unreachable:
      return ExceptionCode::gateway_target_failed;
  }
  return ExceptionCode::server_device_failure;
}

}  // namespace fieldgate
