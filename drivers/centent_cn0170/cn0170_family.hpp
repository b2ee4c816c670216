#pragma once

#include <functional>
#include <set>
#include <string_view>

#include "drivers/centent_cn0170/cn0170_chain.hpp"
#include "drivers/protocol_family.hpp"

namespace fieldgate {

// Centent CN0170 units on one RS-232 daisy chain (shared/protocols/centent-cn0170.md). The
// object belongs to one bus and holds the chain's sticky unit selection (README).
class CententFamily final : public ProtocolFamily {
 public:
  std::string_view name() const override { return "centent-cn0170"; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  // Also takes the model's options as the chain's settings.
  const ModelOptionSpecs& model_options() const override { return cn0170::option_specs(); }
  bool model_options_apply_to_bus() const override { return true; }
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  // Records the unit as configured (chain discovery report, kill plans). The chain's settings
  // come from the first bound node's model (the configuration loader refuses buses whose
  // models' options differ).
  NodeContextPtr bind_node(const NodeAddress& node, const Model& model) override;
  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override;
  // The bus's resync (quiet for a guard time); late replies among what it drained pay their
  // units' debts (README "Late replies").
  asio::awaitable<LinkResync> resync_after_failure(Link& link, const LinkTiming& timing) override;
  asio::awaitable<Reply> transact(Link& link, const NodeAddress& node, const Request& request,
                                  const LinkTiming& timing) override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;
  // `.Un` then `XY?` -> `n"XY?" ?`, then `YX?` -> `n"YX?" ?`: a unit echoes a string it
  // rejects (p.3), so each answer names the string just sent.
  std::optional<AlignmentProof> alignment_proof(NodeContext& node,
                                                const LinkTiming& timing) override;

  const cn0170::Chain& chain() const { return chain_; }
  const cn0170::Options& options() const { return options_; }

 private:
  asio::awaitable<Reply> run(Link& link, int unit, cn0170::Plan plan, std::string what,
                             const LinkTiming& timing);
  asio::awaitable<Reply> read_replies(Link& link, cn0170::Exchange exchange,
                                      const LinkTiming& timing);
  // Mode check and overflow mode, once per unit after the link opened or the unit reset.
  asio::awaitable<std::optional<Reply>> set_up(Link& link, int unit, const LinkTiming& timing);
  asio::awaitable<Reply> kill(Link& link, int unit, const LinkTiming& timing);
  asio::awaitable<Reply> local_read(Link& link, int unit, const Request& request,
                                    const LinkTiming& timing);
  // Sends `query` and reads lines until none arrives within the reply timeout: the units of the
  // `answer` lines in their order (the other lines go to the chain); nullopt if the send failed.
  asio::awaitable<std::optional<std::vector<int>>> ask_units(Link& link, const LinkTiming& timing,
                                                             std::string_view query,
                                                             cn0170::MessageKind answer);
  void flush_log(Link& link);
  std::vector<int> configured_units() const;
  // The LF of a CR LF line end belongs to the reply it ends: taken when it is there and, once
  // the chain has been seen ending lines with CR LF, awaited for the byte gap. Returns a byte
  // that came in its place (the reply is then not to be trusted).
  asio::awaitable<std::optional<std::string>> take_line_end(Link& link, std::string_view last_frame,
                                                            const LinkTiming& timing);

  cn0170::Chain chain_;
  std::set<int> configured_;  // the bound units
  cn0170::Options options_;
  bool options_bound_ = false;
  bool crlf_line_ends_ = false;  // a reply line was seen ending in CR LF
};

FamilyPtr make_centent_cn0170_family();

}  // namespace fieldgate
