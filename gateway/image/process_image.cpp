#include "gateway/image/process_image.hpp"

#include <algorithm>

namespace fieldgate {

std::string_view to_string(NodeState state) {
  switch (state) {
    case NodeState::starting:
      return "starting";
    case NodeState::online:
      return "online";
    case NodeState::offline:
      return "offline";
    case NodeState::faulted:
      return "faulted";
  }
  return "?";
}

int64_t ProcessImage::diagnostic(int index, DiagnosticField field, SteadyTime now) const {
  const auto& n = node(index);
  const auto clamp32 = [](uint64_t v) {
    return static_cast<int64_t>(std::min<uint64_t>(v, 0xffffffffu));
  };
  switch (field) {
    case DiagnosticField::online:
      return n.state == NodeState::online ? 1 : 0;
    case DiagnosticField::last_good_age_ms:
      if (!n.counters.ever_good) return 0xffffffff;
      return clamp32(static_cast<uint64_t>(
          std::chrono::duration_cast<std::chrono::milliseconds>(now - n.counters.last_good)
              .count()));
    case DiagnosticField::consecutive_timeouts:
      return std::min<uint32_t>(n.counters.consecutive_timeouts, 0xffff);
    case DiagnosticField::transactions:
      return clamp32(n.counters.transactions);
    case DiagnosticField::timeouts:
      return clamp32(n.counters.timeouts);
    case DiagnosticField::errors:
      return clamp32(n.counters.errors);
    case DiagnosticField::last_device_error:
      // A code that does not fit is not cut to its low half (0x06020000 would read 0, "no
      // error"): 0xffff says "see last_device_error_code".
      return n.counters.last_device_error > 0xffff
                 ? 0xffff
                 : static_cast<uint16_t>(n.counters.last_device_error);
    case DiagnosticField::last_device_error_code:
      return static_cast<uint32_t>(n.counters.last_device_error);
    case DiagnosticField::action_status:
      return static_cast<uint16_t>(n.action.status);
    case DiagnosticField::action_code:
      return n.action.code;
    case DiagnosticField::action_error:
      return n.action.error;
    case DiagnosticField::node_state:
      return static_cast<uint16_t>(n.state);
    case DiagnosticField::unknown_writes:
      return clamp32(n.counters.unknown_writes);
    case DiagnosticField::unreachable:
      return clamp32(n.counters.unreachable);
    case DiagnosticField::data_age_ms: {
      // The oldest polled value: what a PLC reading this node's points may be served.
      SteadyTime oldest = SteadyTime::max();
      for (std::size_t i = 0; i < n.points.size(); ++i) {
        if (i < n.polled.size() && !n.polled[i]) continue;
        if (!n.points[i].valid) return 0xffffffff;
        oldest = std::min(oldest, n.points[i].updated);
      }
      if (oldest == SteadyTime::max()) return 0;
      return clamp32(static_cast<uint64_t>(
          std::chrono::duration_cast<std::chrono::milliseconds>(now - oldest).count()));
    }
  }
  return 0;
}

}  // namespace fieldgate
