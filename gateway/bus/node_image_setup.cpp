#include "gateway/bus/node_image_setup.hpp"

namespace fieldgate {

namespace {

std::vector<int64_t> configured_setpoints(const NodeConfig& node) {
  std::vector<int64_t> values;
  for (const auto& s : node.model->setpoints) {
    const auto it = node.setpoints.find(s.name);
    values.push_back(it != node.setpoints.end() ? it->second : s.default_value);
  }
  return values;
}

// The node's stale_after, with the period each point is polled at (its poll: overrides applied).
FreshnessPolicy freshness_of(const NodeConfig& node) {
  FreshnessPolicy policy;
  policy.failed_polls = node.stale_after.failed_polls;
  policy.periods = node.stale_after.periods;
  policy.at_least = node.stale_after.at_least;
  for (const auto& p : node.model->points)
    policy.poll_periods.push_back(p.poll_class.empty() ? microseconds{0}
                                                       : node.period_of(p.poll_class));
  return policy;
}

}  // namespace

std::shared_ptr<NodeImage> make_node_image(const NodeConfig& node) {
  auto image = std::make_shared<NodeImage>();
  image->points.assign(node.model->points.size(), {});
  image->setpoints = configured_setpoints(node);
  image->freshness = freshness_of(node);
  return image;
}

void apply_setpoint_changes(NodeImage& image, const NodeConfig& was, const NodeConfig& now) {
  if (was.setpoints != now.setpoints) image.setpoints = configured_setpoints(now);
  image.freshness = freshness_of(now);
}

}  // namespace fieldgate
