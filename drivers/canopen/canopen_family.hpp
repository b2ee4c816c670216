#pragma once

#include "drivers/frame_family.hpp"

namespace fieldgate {

// CANopen (CiA 301 client side) on a SocketCAN interface: a frame family. It checks addresses
// and models at load and tells the CAN bus runtime which frames a node sends (SDO responses,
// heartbeat, EMCY, the TPDOs its points read); the node's SDO transfers run on an SdoChannel.
class CanopenFamily final : public FrameFamily {
 public:
  std::string_view name() const override { return "canopen"; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  void compile_commands(Model& model) const override;
  std::vector<uint32_t> receive_ids(const NodeAddress& node, const Model& model) const override;
  FrameRole classify(const NodeAddress& node, const CanFrame& frame) const override;
  int frame_node(const CanFrame& frame) const override;
};

FamilyPtr make_canopen_family();

}  // namespace fieldgate
