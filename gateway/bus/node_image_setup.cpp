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

}  // namespace

std::shared_ptr<NodeImage> make_node_image(const NodeConfig& node) {
  auto image = std::make_shared<NodeImage>();
  image->points.assign(node.model->points.size(), {});
  image->setpoints = configured_setpoints(node);
  return image;
}

void apply_setpoint_changes(NodeImage& image, const NodeConfig& was, const NodeConfig& now) {
  if (was.setpoints != now.setpoints) image.setpoints = configured_setpoints(now);
}

}  // namespace fieldgate
