#include "gateway/control/control_result.hpp"

namespace fieldgate {

std::string_view to_string(ControlStatus status) {
  switch (status) {
    case ControlStatus::ok:
      return "ok";
    case ControlStatus::no_such_target:
      return "no such target";
    case ControlStatus::out_of_range:
      return "out of range";
    case ControlStatus::writes_disabled:
      return "writes disabled";
    case ControlStatus::not_supported:
      return "not supported";
    case ControlStatus::line_held:
      return "line held by a running action";
    case ControlStatus::value_unknown:
      return "value unknown";
    case ControlStatus::device_error:
      return "device error";
    case ControlStatus::outcome_unknown:
      return "outcome unknown";
    case ControlStatus::unreachable:
      return "unreachable";
  }
  return "unknown status";
}

ControlResult control_result_of(const Reply& reply) {
  const auto text = [&] {
    return reply.text.empty() ? std::string(to_string(reply.status)) : reply.text;
  }();
  switch (reply.status) {
    case Reply::Status::ok:
      return ControlResult::success();
    case Reply::Status::device_error:
      return {ControlStatus::device_error, text, reply.device_code};
    case Reply::Status::timeout:
    case Reply::Status::garbled:
    case Reply::Status::link_down:
      // Buses answer a request that was not sent as unreachable: these went out, or may have
      // (a link that failed while writing).
      return ControlResult::of(ControlStatus::outcome_unknown, text);
    case Reply::Status::unreachable:
      return {ControlStatus::unreachable, text, reply.device_code};
  }
  return ControlResult::of(ControlStatus::outcome_unknown, text);
}

}  // namespace fieldgate
