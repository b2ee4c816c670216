#pragma once

#include <optional>
#include <string_view>

#include "drivers/ims_party_line/ims_chain.hpp"
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
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override;
  asio::awaitable<Reply> transact(Link& link, const NodeAddress& node, const Request& request,
                                  const LinkTiming& timing) override;
  // ESC, ^C and @ of a bus-wide action marked urgent: written at once, even in the middle of
  // another exchange (ESC also clears every unit's half-received line).
  asio::awaitable<Reply> send_urgent(Link& link, const NodeAddress& node,
                                     const Request& request) override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;

  const ims::ChainShadow& shadow() const { return shadow_; }

 private:
  asio::awaitable<Reply> transact_global(Link& link, const Request& request,
                                         const LinkTiming& timing);

  ims::ChainShadow shadow_;
};

// The decision parts of transact(), pure so the digest's transcripts test them.

// nullopt when `echo` (one line, LF included) is the echo of the request to `node`; else the
// garbled reply that says why not.
std::optional<Reply> check_ims_echo(const NodeAddress& node, const Request& request,
                                    std::string_view echo);
// What a result line means for a query.
Reply interpret_ims_result(const NodeAddress& node, const Request& request, std::string_view line);
// Everything a unit sent back after the request, as if it all arrived before the deadline:
// stray blank lines, the echo, and the result line or completion.
Reply interpret_ims_reply(const NodeAddress& node, const Request& request,
                          std::string_view received);

}  // namespace fieldgate
