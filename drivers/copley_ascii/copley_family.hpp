#pragma once

#include "drivers/protocol_family.hpp"

namespace fieldgate {

class CopleyFamily final : public ProtocolFamily {
 public:
  std::string_view name() const override { return "copley-ascii"; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  // Notes whether the gateway amplifier (node 0) is configured by axis letter: its proof of
  // alignment then uses the axis form, which a multi-axis amplifier needs.
  NodeContextPtr bind_node(const NodeAddress& node, const Model& model) override;
  // The amplifier starts at 9600 baud after power-up, reset and break (ASCII guide §1.2, §4.1);
  // 0x90 is RAM-only. If it does not answer at the configured rate, switch it from 9600.
  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override;
  asio::awaitable<Reply> transact(Link& link, const NodeAddress& node, const Request& request,
                                  const LinkTiming& timing) override;
  std::optional<std::string> pipelined_request(NodeContext& node, const Request& request) override;
  // A node other than 0 is reached through the gateway amplifier over CAN: its reply timeout
  // must exceed the amplifier's CAN timeout, so that e 32 for an absent node is its answer.
  // The proof of alignment, on the gateway amplifier (every node's replies come through it):
  // `g f0x32` answers `e 15` (0x32 is RAM-only, gotcha 16), then `g r0x90` answers a baud
  // rate. No poll asks for e 15, and the second answer differs from the first.
  std::optional<AlignmentProof> alignment_proof(NodeContext& node,
                                                const LinkTiming& timing) override;
  NodeTimingNeed node_timing_need(const NodeAddress& node, const LinkTiming& bus) const override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;

 private:
  bool gateway_wants_axis_ = false;  // the gateway amplifier answered only the `.a` form
  char gateway_axis_ = 0;            // the first axis letter configured on node 0, if any
};

// The gateway amplifier's CAN timeout when the bus does not give forward_timeout. The ASCII
// guide gives none; this is an assumption to replace with the installed amplifiers' value.
inline constexpr std::chrono::milliseconds kCopleyDefaultCanTimeout{100};
// What a forwarded reply needs on top of the CAN timeout: the gateway amplifier's own
// processing and the reply's first byte.
inline constexpr std::chrono::milliseconds kCopleyForwardMargin{50};

// The decision part of transact(): what a complete reply line means for this request.
Reply interpret_copley_reply(const NodeAddress& node, const Request& request,
                             std::string_view line);

}  // namespace fieldgate
