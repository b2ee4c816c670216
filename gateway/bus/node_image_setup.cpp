#include "gateway/bus/node_image_setup.hpp"

namespace fieldgate {

std::shared_ptr<NodeImage> make_node_image(const NodeConfig& node) {
  auto image = std::make_shared<NodeImage>();
  image->points.assign(node.model->points.size(), {});
  for (const auto& s : node.model->setpoints) {
    const auto it = node.setpoints.find(s.name);
    image->setpoints.push_back(it != node.setpoints.end() ? it->second : s.default_value);
  }
  return image;
}

}  // namespace fieldgate
