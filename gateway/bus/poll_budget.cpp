#include "gateway/bus/poll_budget.hpp"

#include <set>

namespace fieldgate {

BusBudget compute_poll_budget(const BusConfig& bus) {
  BusBudget budget{bus.name, 0};
  const double char_us = serial_char_time_us(bus.transport.serial);
  for (const auto& node : bus.nodes) {
    std::set<std::string> seen;  // points sharing one request cost one transaction
    for (const auto& p : node.model->points) {
      if (!p.read || p.poll_class.empty() || p.read->object) continue;
      if (!seen.insert(p.read->request.source()).second) continue;
      Request r{p.read->request.source(), Request::Expect::values, p.read->format};
      r.compiled = p.read->request.compiled();
      const double chars = static_cast<double>(bus.family->estimate_wire_chars(node.address, r));
      const double seconds =
          (chars * char_us + static_cast<double>(bus.timing.turnaround.count() +
                                                 bus.timing.inter_frame_gap.count())) /
          1e6;
      const double period = static_cast<double>(node.period_of(p.poll_class).count()) / 1e6;
      if (period > 0) budget.wire_seconds_per_second += seconds / period;
    }
  }
  return budget;
}

}  // namespace fieldgate
