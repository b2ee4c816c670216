#pragma once

#include <memory>

#include "gateway/config/gateway_config.hpp"
#include "gateway/image/process_image.hpp"

namespace fieldgate {

// A configured node's image before anything was read from it, on every kind of bus: each point
// invalid, each setpoint at the node's configured value or else the model's default, its
// freshness policy from its bus's stale_after and its poll periods.
std::shared_ptr<NodeImage> make_node_image(const NodeConfig& node);
// A node a reload kept on its bus (`was` -> `now`): the setpoints the PLC wrote stay unless the
// site changed the node's configured ones, which then take their configured values. Its
// freshness policy follows its new poll periods.
void apply_setpoint_changes(NodeImage& image, const NodeConfig& was, const NodeConfig& now);

}  // namespace fieldgate
