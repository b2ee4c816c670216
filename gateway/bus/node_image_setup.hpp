#pragma once

#include <memory>

#include "gateway/config/gateway_config.hpp"
#include "gateway/image/process_image.hpp"

namespace fieldgate {

// A configured node's image before anything was read from it, on every kind of bus: each point
// invalid, each setpoint at the node's configured value or else the model's default.
std::shared_ptr<NodeImage> make_node_image(const NodeConfig& node);

}  // namespace fieldgate
