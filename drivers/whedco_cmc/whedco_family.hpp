#pragma once

#include <map>
#include <optional>
#include <string>
#include <utility>

#include "drivers/protocol_family.hpp"
#include "drivers/whedco_cmc/whedco_codec.hpp"

namespace fieldgate {

// What a reply showed about its unit beyond its values.
struct WhedcoFindings {
  std::optional<whedco::StatusForm> status_form;  // a status word proved its form
  bool unit_fault_number = false;                 // FC answered a number (non-echo)
};

// Whedco CMC coordinated motion controllers: one CMC-0 per address digit, several on one
// RS-422/485 line, each with up to four axes W, X, Y, Z named in the commands.
//
// Sticky state of the line, kept here because a family instance belongs to one bus: the unit
// ratio of every axis seen (so internal units can be converted to the user units the wire
// carries), and whether the line must be voided before the next request.
class WhedcoFamily final : public ProtocolFamily {
 public:
  std::string_view name() const override { return "whedco-cmc"; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override;
  asio::awaitable<Reply> transact_node(Link& link, NodeContext& node, const Request& request,
                                       const LinkTiming& timing) override;
  std::optional<std::string> pipelined_request(NodeContext& node, const Request& request) override;
  const ModelOptionSpecs& model_options() const override;
  // The node's context carries its model's status_layout.
  NodeContextPtr bind_node(const NodeAddress& node, const Model& model) override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;
  // `4!` -> the prompt alone (a line with `!` is ignored, §5.17), then `4FC` -> a value or text
  // before the prompt: in echo format each answer also repeats its own line.
  std::optional<AlignmentProof> alignment_proof(NodeContext& node,
                                                const LinkTiming& timing) override;

  // The communication format a node was configured with (NodeAddress::axis carries it: the
  // address of a CMC-0 has no axis letter).
  static whedco::EchoMode echo_mode(const NodeAddress& node);

 private:
  enum class Resync { none, void_line, void_and_drain };
  struct BoundNode : NodeContext {
    using NodeContext::NodeContext;
    // Model option status_layout. Not detected: no word tells the layouts apart, as bit 2 may
    // be busy in one and a lasting state (homed) in the other.
    whedco::StatusLayout layout = whedco::StatusLayout::busy_first;
  };

  asio::awaitable<Reply> exchange(Link& link, const BoundNode& node, const std::string& command,
                                  Request::Expect expect, NumberFormat format,
                                  whedco::QueryKind kind, int unit_ratio, const LinkTiming& timing);
  asio::awaitable<void> resync(Link& link, const LinkTiming& timing);
  // The first exchange with a unit since the port opened: reads FC, and clears the power-up
  // state (Power Failure, every axis faulted) with WB, as the manual asks after power-up.
  // True when the unit was met before this link opening and reads its power-up state again.
  asio::awaitable<bool> first_contact(Link& link, const BoundNode& node, const LinkTiming& timing);
  void note_power_failure(Link& link, int unit, const whedco::PreparedCommand& prepared,
                          Reply& reply);
  // The unit ratio a command's wire form is scaled by: 1 if it carries no quantity, the ratio
  // read from the unit before, or nullopt if UR? must be read first.
  std::optional<int> known_unit_ratio(int unit, const whedco::PreparedCommand& prepared) const;

  std::map<std::pair<int, char>, int> unit_ratios_;  // (unit, axis) -> pulses per user unit
  std::map<int, bool> contacted_;
  std::map<int, bool> power_failure_reported_;  // since the unit's FC last read functional
  std::map<int, whedco::StatusForm> status_forms_;
  std::map<int, int64_t> unit_functional_;
  WhedcoFindings findings_;  // of the last exchange
  Resync resync_ = Resync::none;
};

// One exchange as interpret_whedco_reply() needs to know it.
struct WhedcoExchange {
  std::string line;  // address and command as sent, without CR: what an echo repeats
  // What the family learned of this unit: how it prints status words, and the non-echo FC
  // number that means Unit Functional (0 or 8, learned after a WB; both taken until then).
  std::optional<whedco::StatusForm> status_form;
  std::optional<int64_t> unit_functional;
  whedco::EchoMode mode = whedco::EchoMode::automatic;
  Request::Expect expect = Request::Expect::ack;
  NumberFormat format = NumberFormat::decimal;
  whedco::QueryKind kind = whedco::QueryKind::plain;
  int unit_ratio = 1;  // factor from the reply's user units to internal units
};

// The decision part of transact(): what a complete frame (up to the `*` prompt) means.
// Fault queries give two values: the code and a faulted flag (axis: code != 8; unit: the echo
// texts != Unit Functional, a non-echo number != the learned functional number, 0 or 8).
Reply interpret_whedco_reply(const WhedcoExchange& exchange, std::string_view frame,
                             WhedcoFindings* findings = nullptr);

}  // namespace fieldgate
