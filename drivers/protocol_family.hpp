#pragma once

#include <boost/asio/awaitable.hpp>

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "drivers/alignment_proof.hpp"
#include "drivers/link.hpp"
#include "mapping/diagnostics.hpp"
#include "mapping/model.hpp"
#include "mapping/model_options.hpp"

namespace fieldgate {

// A node's place on its bus, canonicalised by the family from the config's `address`.
struct NodeAddress {
  std::string text;  // canonical form, for logs and maps
  int number = 0;    // node ID, unit number, device number
  char axis = 0;     // axis letter where the family has one, else 0

  // A node addressed by its number alone: the number is also its canonical text.
  static NodeAddress numbered(int number) { return NodeAddress{std::to_string(number), number, 0}; }
};

struct Request {
  enum class Expect { ack, values };
  std::string command;  // rendered command, without addressing
  Expect expect = Expect::ack;
  NumberFormat format = NumberFormat::decimal;
  // For every node on the link (a global stop or kill): the family sends it without a node
  // address, as its manual defines the broadcast form.
  bool bus_wide = false;
  // A command from a model's template: the family's form of it compiled at load, and the
  // template's argument values. A family that compiles its commands runs these; `command` is
  // then only what logs and the wire trace show.
  std::shared_ptr<const CompiledCommand> compiled = {};
  std::vector<int64_t> arguments = {};

  // The command `command` makes with the values `lookup` gives its placeholders.
  static Request of_template(const CommandTemplate& command,
                             const std::function<int64_t(std::string_view)>& lookup,
                             bool bus_wide = false) {
    return Request{command.render(lookup), Expect::ack,
                   NumberFormat::decimal,  bus_wide,
                   command.compiled(),     command.arguments(lookup)};
  }
};

struct Reply {
  enum class Status {
    ok,            // acknowledged (and values, for a read)
    device_error,  // the controller refused: code and text say why
    unreachable,   // a forwarding node says the target does not answer
    timeout,       // nothing, or nothing complete, within the reply timeout
    garbled,       // bytes arrived that are not a valid reply to this request
    link_down,     // the transport failed
  };
  Status status = Status::timeout;
  std::vector<int64_t> values;
  int64_t device_code = 0;
  std::string text;  // error text, or the offending bytes for garbled replies
  // The exchange found the controller in its power-up state after the gateway had set it up (a
  // power cycle or reset it could only infer): whatever ran on it before is lost.
  bool controller_reset = false;

  // A reply without values: how it came out, why, and the device's own code where it gave one.
  static Reply of(Status status, std::string text = {}, int64_t device_code = 0) {
    Reply reply;
    reply.status = status;
    reply.text = std::move(text);
    reply.device_code = device_code;
    return reply;
  }
};

std::string_view to_string(Reply::Status status);

// One configured node as its family sees it: the address, and whatever the family derived from
// the node's model when the bus was built (Family::bind_node). A family with per-node
// settings or state derives its own; the context is opaque to the bus, which hands it back to
// transact().
class NodeContext {
 public:
  explicit NodeContext(NodeAddress address) : address_(std::move(address)) {}
  virtual ~NodeContext() = default;
  const NodeAddress& address() const { return address_; }

 private:
  NodeAddress address_;
};

using NodeContextPtr = std::shared_ptr<NodeContext>;

// A controller family as configuration and every bus see it: the name, node addresses, the
// model checks and options, and a node's context. Two shapes derive from it: a stream family
// (ProtocolFamily, below), which exchanges bytes over a Link one transaction at a time, and a
// frame family (FrameFamily, drivers/frame_family.hpp), which runs on a CAN frame bus. The
// registry and the configuration hand out this base; each bus runtime asks for its shape once,
// when it is built.
class Family {
 public:
  virtual ~Family() = default;
  virtual std::string_view name() const = 0;
  virtual std::optional<NodeAddress> parse_address(std::string_view text,
                                                   std::string& error) const = 0;
  // The options a model of this family may set (`options:`), with types, defaults and ranges;
  // validate_model checks a model's options against them with check_model_options.
  virtual const ModelOptionSpecs& model_options() const;
  // True where the options set the whole bus's behaviour (a chain's framing): every node of a
  // bus must then run models whose options agree, which the configuration loader checks.
  virtual bool model_options_apply_to_bus() const { return false; }
  // Family-specific checks of a model once its family is known. The default checks the model's
  // options against model_options().
  virtual void validate_model(const Model& model, Diagnostics& diagnostics) const;
  // Compiles the model's command templates (point writes, action steps) into the form the
  // family runs, once, while the configuration loads; validate_model has reported any template
  // the family cannot compile. The default keeps none: the family sends the rendered text.
  virtual void compile_commands(Model& model) const;
  // Called once for every configured node when its bus is built, with the node's model (which
  // validate_model accepted): the family reads what changes the exchange with that node (its
  // model options) and returns the node's context, which transact() then receives. The default
  // context holds the address only.
  virtual NodeContextPtr bind_node(const NodeAddress& node, const Model& model);
  // The least reply timeout a node needs, and why (e.g. a node reached through a forwarding
  // device must outwait that device's own timeout, or its "not reachable" reply arrives late).
  // The bus uses it where no reply_timeout is configured; a configured value below it is
  // warned about. The default: nothing beyond the bus's timing.
  struct NodeTimingNeed {
    std::chrono::microseconds reply_timeout{0};
    std::string why;
  };
  virtual NodeTimingNeed node_timing_need(const NodeAddress& node, const LinkTiming& bus) const;
  // Characters on the wire for a request and its typical reply (poll budget estimate).
  virtual std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const;
};

// The stream shape of a family: addressing, framing and reply grammar of one controller family
// on a byte stream. The codec parts are pure functions tested against the manuals' transcripts;
// transact() glues them to a Link for one request/reply exchange.
class ProtocolFamily : public Family {
 public:
  // Runs every time the transport (re)opens, before the first transaction.
  virtual asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing);
  // One request/reply exchange with a bound node (the bus calls this one). A family overrides
  // either transact_node(), where it keeps per-node settings in its context, or transact() by
  // address, where it has none; each default calls the other.
  virtual asio::awaitable<Reply> transact_node(Link& link, NodeContext& node,
                                               const Request& request, const LinkTiming& timing);
  // The bytes transact_node() would write first for `request`, were it called now, where nothing
  // but discard_input() comes before that send(). nullopt where something else would (a resync,
  // a query of its own, a refusal, pacing) or might, and by default. The bus may then send the
  // request ahead (Link::send_ahead) the moment the exchange before it has been accepted, and
  // transact_node() finds it sent. Bytes that differ from what transact_node() then sends cost
  // the bus a proof of alignment (it logs them as an error), never a reply taken for another.
  virtual std::optional<std::string> pipelined_request(NodeContext& node, const Request& request);
  // By address, for callers that hold no context (tests, tools): the context configure_node()
  // kept for the address, or else one bound to a model without options (the options' defaults).
  virtual asio::awaitable<Reply> transact(Link& link, const NodeAddress& node,
                                          const Request& request, const LinkTiming& timing);
  // Binds a node for callers that address it by address (see transact() by address) and keeps
  // the context.
  NodeContext& configure_node(const NodeAddress& node, const Model& model);
  NodeContext& context_of(const NodeAddress& node);
  // Called by the bus after a timeout, a garbled or a partial reply (and after a reply that left
  // unexplained bytes behind), before the link carries anything else: replies carry no tag, so
  // a late one would answer the next request. The default drains the line until it has been
  // quiet for guard_time(timing) (Link::resync), giving up after ten guard times. A family whose
  // manual offers a cheaper way (an echo to check, a prompt) may override it.
  virtual asio::awaitable<LinkResync> resync_after_failure(Link& link, const LinkTiming& timing);
  // The exchange that proves the line is in step again after such a failure
  // (drivers/alignment_proof.hpp): the bus runs it once resync_after_failure() found the line
  // quiet, and trusts no reply until it passed. `node` is whom to address where the proof needs
  // a node (the bus tries the failed node first, then the others that are not offline); a proof
  // on a device every node sits behind (a gateway amplifier) may ignore it. nullopt: the
  // family's replies prove themselves and the quiet guard suffices.
  virtual std::optional<AlignmentProof> alignment_proof(NodeContext& node,
                                                        const LinkTiming& timing);
  // Sends a command that must not wait for the line (see CommandOptions::urgent). The default
  // refuses: a family without such commands reports it instead of corrupting a transaction.
  virtual asio::awaitable<Reply> send_urgent(Link& link, const NodeAddress& node,
                                             const Request& request);

 private:
  std::map<std::string, NodeContextPtr, std::less<>> by_address_;
};

using FamilyPtr = std::shared_ptr<Family>;

FamilyPtr make_family(std::string_view name);
std::vector<std::string> family_names();

}  // namespace fieldgate
