#pragma once

#include "drivers/protocol_family.hpp"

namespace fieldgate {

class CopleyFamily final : public ProtocolFamily {
 public:
  std::string_view name() const override { return "copley-ascii"; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  // The amplifier starts at 9600 baud after power-up, reset and break (ASCII guide §1.2, §4.1);
  // 0x90 is RAM-only. If it does not answer at the configured rate, switch it from 9600.
  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override;
  asio::awaitable<Reply> transact(Link& link, const NodeAddress& node, const Request& request,
                                  const LinkTiming& timing) override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;
};

// The decision part of transact(): what a complete reply line means for this request.
Reply interpret_copley_reply(const NodeAddress& node, const Request& request,
                             std::string_view line);

}  // namespace fieldgate
