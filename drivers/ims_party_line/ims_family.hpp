#pragma once

#include <chrono>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "drivers/ims_party_line/ims_chain.hpp"
#include "drivers/ims_party_line/ims_exchange.hpp"
#include "drivers/ims_party_line/ims_readings.hpp"
#include "drivers/protocol_family.hpp"

namespace fieldgate {

// IMS indexers on an RS-422 party line (shared/protocols/ims-indexer.md). One instance per
// chain: the chain shadow (pacing, motion and EEPROM guards) lives here. See README.md for the
// readings of the manual's ambiguities.
class ImsPartyLineFamily final : public ProtocolFamily {
 public:
  std::string_view name() const override { return "ims-party-line"; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  const ModelOptionSpecs& model_options() const override;
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  // The unit's pinned readings (options result_placement, echo_linefeed) and its limits
  // (pacing_step_rate, save_interval) go to the chain's readings and shadow: one fast unit paces
  // the whole chain, so they are the chain's to keep.
  NodeContextPtr bind_node(const NodeAddress& node, const Model& model) override;
  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override;
  // The bus's resync (quiet for a guard time), with what it drained accounted as late replies.
  asio::awaitable<LinkResync> resync_after_failure(Link& link, const LinkTiming& timing) override;
  asio::awaitable<Reply> transact(Link& link, const NodeAddress& node, const Request& request,
                                  const LinkTiming& timing) override;
  std::optional<std::string> pipelined_request(NodeContext& node, const Request& request) override;
  // ESC, ^C and @ of a bus-wide action marked urgent: written at once, even in the middle of
  // another exchange (ESC also clears every unit's half-received line).
  asio::awaitable<Reply> send_urgent(Link& link, const NodeAddress& node,
                                     const Request& request) override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;
  // `<name>^` answered by the echo of `^` and a result, then `<name>Z` by the echo of `Z` and a
  // result: the echo names the command it answers, whatever the values.
  std::optional<AlignmentProof> alignment_proof(NodeContext& node,
                                                const LinkTiming& timing) override;

  const ims::ChainShadow& shadow() const { return shadow_; }
  const ims::UnitReadings& readings() const { return readings_; }
  const ims::LateReplies& late_replies() const { return late_; }
  void pin(char name, ims::ReadingPins pins) { readings_.pin(name, pins); }

  // How long a debt of late replies is kept (README "Late replies").
  static std::chrono::microseconds late_window(const LinkTiming& timing);

 private:
  asio::awaitable<Reply> transact_global(Link& link, const Request& request,
                                         const LinkTiming& timing);
  // The glue of an ims::Exchange: sends the line, reads what the exchange asks for, writes its
  // log lines, and drains the line after a garbled reply.
  asio::awaitable<Reply> exchange(Link& link, const NodeAddress& node, const Request& request,
                                  const LinkTiming& timing, bool paced);
  // M0, then `^` until the unit is idle: the jog a new index for it aborts.
  asio::awaitable<Reply> end_jog(Link& link, const NodeAddress& node, const Request& request,
                                 const LinkTiming& timing);
  static constexpr std::chrono::seconds kJogRampDownPatience{10};
  static constexpr std::chrono::milliseconds kJogPollInterval{50};
  // Everything waiting in the input, read and accounted (LateReplies::stray), then dropped.
  asio::awaitable<void> flush(Link& link);
  // After a bad reply: read until the line has been quiet for a byte timeout, accounting it.
  asio::awaitable<void> drain(Link& link, const LinkTiming& timing);
  // A line for the gateway's log (a link note): the reading each unit was found to use, late
  // replies written off.
  static void log(Link& link, int level, const std::optional<std::string>& text);

  ims::ChainShadow shadow_;
  ims::UnitReadings readings_;
  ims::LateReplies late_;
  std::map<char, ims::UnitTrack> units_;
};

}  // namespace fieldgate
