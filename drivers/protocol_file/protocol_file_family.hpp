#pragma once

#include <set>
#include <string>
#include <vector>

#include "drivers/protocol_family.hpp"
#include "drivers/protocol_file/protocol_exchange.hpp"
#include "drivers/protocol_file/protocol_spec.hpp"

namespace fieldgate::protocol_file {

// The device code of a command the family would not send (an argument its field cannot carry).
inline constexpr int64_t kNotSent = 0xFFF9;

// A command of a model compiled against the protocol at load: the protocol command it runs, and
// for each of its parameters either a constant of the model's text or the index of the
// template's placeholder that gives it.
struct CompiledProtocolCommand final : CompiledCommand {
  struct Argument {
    bool constant = false;
    int64_t value = 0;
    std::size_t placeholder = 0;
  };
  ProtocolSpecPtr spec;  // keeps `command` alive
  const CommandSpec* command = nullptr;
  std::vector<Argument> arguments;
};

// A stream family whose protocol is a file (docs/protocol-files.md): its commands, replies,
// confirmations, start-up and alignment proof are data, run by this one class.
class ProtocolFileFamily final : public ProtocolFamily {
 public:
  explicit ProtocolFileFamily(ProtocolSpecPtr spec) : spec_(std::move(spec)) {}

  std::string_view name() const override { return spec_->name; }
  const ProtocolSpec& spec() const { return *spec_; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  void compile_commands(Model& model) const override;
  NodeContextPtr bind_node(const NodeAddress& node, const Model& model) override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;

  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override;
  asio::awaitable<Reply> transact(Link& link, const NodeAddress& node, const Request& request,
                                  const LinkTiming& timing) override;
  std::optional<std::string> pipelined_request(NodeContext& node, const Request& request) override;
  std::optional<AlignmentProof> alignment_proof(NodeContext& node,
                                                const LinkTiming& timing) override;

  // A model's command text compiled against the protocol: "name" or "name {p} 5 ...".
  std::shared_ptr<const CompiledProtocolCommand> compile(const CommandTemplate& text,
                                                         std::string& error) const;

 private:
  // A request as the protocol runs it: its command, argument values and address text; or why
  // it cannot run.
  struct Resolved {
    const CommandSpec* command = nullptr;
    std::vector<int64_t> arguments;
    std::string address;
    std::string refusal;  // not empty: refused, and why
  };
  Resolved resolve(const NodeAddress& node, const Request& request) const;
  void check_capture_fills_point(const PointDef& point, const CommandSpec& command,
                                 Diagnostics& diagnostics) const;
  // One command and its confirmations, as the device must answer them.
  asio::awaitable<Reply> run(Link& link, const CommandSpec& command,
                             const std::vector<int64_t>& arguments, std::string_view address,
                             const LinkTiming& timing);
  // The start-up's bounded loop (StartupStep::discover), with what it found in the log.
  asio::awaitable<void> discover(Link& link, const StartupStep& step, const LinkTiming& timing);
  // One request and its reply (none for a command the device does not answer); a refusal
  // without a code is then explained by the file's refusal_query, where it has one.
  asio::awaitable<ReplyReading> exchange(Link& link, const CommandSpec& command,
                                         const std::vector<int64_t>& arguments,
                                         std::string_view address, const LinkTiming& timing);
  asio::awaitable<ReplyReading> exchange_once(Link& link, const CommandSpec& command,
                                              const std::vector<int64_t>& arguments,
                                              std::string_view address, const LinkTiming& timing);

  ProtocolSpecPtr spec_;
  std::set<int> nodes_;  // bound node numbers, for start-up commands sent to every node
};

FamilyPtr make_protocol_file_family(ProtocolSpecPtr spec);

}  // namespace fieldgate::protocol_file
