#include "drivers/protocol_family.hpp"

namespace fieldgate {

std::string_view to_string(Reply::Status status) {
  switch (status) {
    case Reply::Status::ok:
      return "ok";
    case Reply::Status::device_error:
      return "device error";
    case Reply::Status::unreachable:
      return "unreachable";
    case Reply::Status::timeout:
      return "timeout";
    case Reply::Status::garbled:
      return "garbled reply";
    case Reply::Status::link_down:
      return "link down";
  }
  return "?";
}

const ModelOptionSpecs& Family::model_options() const {
  static const ModelOptionSpecs none;
  return none;
}

void Family::validate_model(const Model& model, Diagnostics& diagnostics) const {
  check_model_options(model, name(), model_options(), diagnostics);
}

void Family::compile_commands(Model&) const {}

NodeContextPtr Family::bind_node(const NodeAddress& node, const Model&) {
  return std::make_shared<NodeContext>(node);
}

namespace {

// The whole address: a family may canonicalise two addresses of one node to one text and tell
// them apart by the rest (Whedco's echo mode).
std::string address_key(const NodeAddress& node) {
  return node.text + '\0' + std::to_string(node.number) + '\0' + node.axis;
}

}  // namespace

NodeContext& ProtocolFamily::configure_node(const NodeAddress& node, const Model& model) {
  auto& slot = by_address_[address_key(node)];
  slot = bind_node(node, model);
  return *slot;
}

NodeContext& ProtocolFamily::context_of(const NodeAddress& node) {
  auto& slot = by_address_[address_key(node)];
  if (!slot) {
    Model unconfigured;
    unconfigured.name = "(none)";
    unconfigured.family = std::string(name());
    slot = bind_node(node, unconfigured);
  }
  return *slot;
}

asio::awaitable<Reply> ProtocolFamily::transact_node(Link& link, NodeContext& node,
                                                     const Request& request,
                                                     const LinkTiming& timing) {
  co_return co_await transact(link, node.address(), request, timing);
}

std::optional<std::string> ProtocolFamily::pipelined_request(NodeContext&, const Request&) {
  return std::nullopt;
}

asio::awaitable<Reply> ProtocolFamily::transact(Link& link, const NodeAddress& node,
                                                const Request& request, const LinkTiming& timing) {
  co_return co_await transact_node(link, context_of(node), request, timing);
}

asio::awaitable<void> ProtocolFamily::on_link_open(Link&, const LinkTiming&) {
  co_return;
}

asio::awaitable<LinkResync> ProtocolFamily::resync_after_failure(Link& link,
                                                                 const LinkTiming& timing) {
  const auto guard = guard_time(timing, link.char_time_us());
  co_return co_await link.resync(guard, 10 * guard);
}

std::optional<AlignmentProof> ProtocolFamily::alignment_proof(NodeContext&, const LinkTiming&) {
  return std::nullopt;
}

asio::awaitable<Reply> ProtocolFamily::send_urgent(Link&, const NodeAddress&, const Request& r) {
  co_return Reply::of(
      Reply::Status::device_error,
      "family " + std::string(name()) + " has no urgent commands ('" + r.command + "')");
}

Family::NodeTimingNeed Family::node_timing_need(const NodeAddress&, const LinkTiming&) const {
  return {};
}

std::size_t Family::estimate_wire_chars(const NodeAddress&, const Request& request) const {
  return request.command.size() + 16;
}

}  // namespace fieldgate
