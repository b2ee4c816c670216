#include "gateway/image/point_freshness.hpp"

#include <algorithm>

namespace fieldgate {

namespace {

bool polled(const NodeImage& node, const PointDef& def, std::size_t point_index) {
  if (point_index < node.polled.size()) return node.polled[point_index];
  return def.readable() && !def.poll_class.empty();
}

}  // namespace

std::chrono::microseconds point_age_bound(const NodeImage& node, const Model& model,
                                          std::size_t point_index) {
  using std::chrono::microseconds;
  const FreshnessPolicy& policy = node.freshness;
  if (point_index >= model.points.size() || policy.periods == 0) return microseconds{0};
  const PointDef& def = model.points[point_index];
  if (!polled(node, def, point_index)) return microseconds{0};
  microseconds period{0};
  if (point_index < policy.poll_periods.size()) period = policy.poll_periods[point_index];
  if (period.count() <= 0)
    if (const auto* c = model.find_poll_class(def.poll_class)) period = c->period;
  if (period.count() <= 0) return microseconds{0};
  if (point_index < node.points.size())
    period = std::max(period, node.points[point_index].interval);
  return std::max(period * policy.periods, policy.at_least);
}

bool point_is_fresh(const NodeImage& node, const Model& model, std::size_t point_index,
                    SteadyTime now) {
  if (point_index >= node.points.size() || point_index >= model.points.size()) return false;
  const PointValue& value = node.points[point_index];
  if (!value.valid) return false;
  if (!polled(node, model.points[point_index], point_index) || node.action.holding_line)
    return true;
  const FreshnessPolicy& policy = node.freshness;
  if (policy.failed_polls > 0 && value.failed_polls >= policy.failed_polls) return false;
  const auto bound = point_age_bound(node, model, point_index);
  return bound.count() <= 0 || now - value.updated <= bound;
}

}  // namespace fieldgate
