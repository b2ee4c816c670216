#pragma once

#include "drivers/protocol_family.hpp"

namespace fieldgate {

// CANopen (CiA 301 client side) on a SocketCAN interface. The family checks addresses and
// models at load; the transfers themselves run in the CAN bus runtime (gateway/bus/can_bus.cpp),
// which overlaps SDO transfers of different nodes and consumes heartbeat, EMCY and PDOs, so
// the byte-stream transact() of serial families does not apply.
class CanopenFamily final : public ProtocolFamily {
 public:
  std::string_view name() const override { return "canopen"; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  asio::awaitable<Reply> transact(Link& link, const NodeAddress& node, const Request& request,
                                  const LinkTiming& timing) override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;
};

FamilyPtr make_canopen_family();

}  // namespace fieldgate
