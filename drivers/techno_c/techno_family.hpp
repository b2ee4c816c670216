#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "drivers/protocol_family.hpp"
#include "drivers/techno_c/techno_codec.hpp"
#include "drivers/techno_c/techno_model.hpp"

namespace fieldgate {

// Techno/isel C-series controllers (drivers/techno_c/README.md). A capital-letter motion holds
// the line until the motion ends: transact() waits for its handshake as long as the motion
// takes (from the command's distances and speeds and the model's acceleration), and a stop byte
// sent by send_urgent() meanwhile ends that wait.
class TechnoFamily final : public ProtocolFamily {
 public:
  std::string_view name() const override { return "techno-c"; }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override;
  const ModelOptionSpecs& model_options() const override { return techno::option_specs(); }
  void validate_model(const Model& model, Diagnostics& diagnostics) const override;
  // The node's context carries its model's profile and what the family knows of the controller.
  NodeContextPtr bind_node(const NodeAddress& node, const Model& model) override;
  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override;
  asio::awaitable<Reply> transact_node(Link& link, NodeContext& node, const Request& request,
                                       const LinkTiming& timing) override;
  asio::awaitable<Reply> send_urgent(Link& link, const NodeAddress& node,
                                     const Request& request) override;
  // The bus's guard after a failure is the family's own resync: it is not waited twice.
  asio::awaitable<LinkResync> resync_after_failure(Link& link, const LinkTiming& timing) override;
  std::size_t estimate_wire_chars(const NodeAddress& node, const Request& request) const override;

  // How long transact() waits for the handshake of `command` at this moment (for tests).
  std::chrono::microseconds reply_budget(const NodeAddress& node, std::string_view command,
                                         const LinkTiming& timing);

 private:
  using Clock = std::chrono::steady_clock;

  // What the family knows of one controller between transactions.
  struct NodeState {
    std::array<std::optional<int64_t>, 3> position;   // steps, X Y Z, where known
    std::array<std::optional<double>, 3> home_speed;  // sent with `d` since the link opened
    int plane = 0;
    // A lower-case motion (or a stop's ramp) may still be moving axes: in_motion is inferred
    // from its estimated end and from positions that still change between polls.
    bool motion_pending = false;
    Clock::time_point motion_estimated_end{};
    Clock::time_point motion_deadline{};  // by when the controller answers again at the latest
    std::optional<std::array<int64_t, 3>> last_reported;
    // Where the running lower-case motion ends, where known, and whether that is a commanded
    // target (a move) rather than a guess (homing, a stop's ramp).
    std::array<std::optional<int64_t>, 3> expected_end;
    bool expects_target = false;
    bool moved = false;  // the polled positions changed since the acknowledge
    Clock::time_point last_change{};
    int64_t motion_error = 0;  // field kFieldMotionError
    // An error character that came right after a query's answer: taken before the next
    // exchange, as if it had come a moment later, so that the answer it followed (sampled
    // while the axis still moved) reports the motion as it was.
    int64_t error_after_reply = 0;
    bool initialised = false;  // init_on_connect has run since the link opened
    // Whether this controller answers `P` during a lower-case motion (false: it keeps the query
    // in its input buffer until the motion ends, p.73), once seen.
    std::optional<bool> queries_deferred;
  };

  // A controller on the line: its model's profile and its state.
  struct BoundNode : NodeContext {
    BoundNode(const NodeAddress& address, techno::Profile bound_profile)
        : NodeContext(address), profile(std::move(bound_profile)) {}
    techno::Profile profile;
    NodeState state;
    bool active = false;  // addressed since the link opened (a stop's ramp concerns it)
    // The controller was seen with its axes defined: it took the family's axes definition, or
    // answered any other command (an undefined card answers only `4`, p.69). A later `4` means
    // it lost the definition (power cycle) and its positions with it.
    bool seen_defined = false;
  };

  struct Waited {
    LinkRead read;
    bool interrupted = false;  // a stop or reset went out while waiting
  };

  // The profile of the whole line (stop bytes and ramps reach every controller): the bound
  // nodes' profiles merged conservatively.
  const techno::Profile& profile();
  BoundNode& active(NodeContext& node);
  std::chrono::microseconds reply_budget(BoundNode& node, std::string_view command,
                                         const LinkTiming& timing);
  techno::MotionContext motion_context(const BoundNode& node);
  asio::awaitable<Reply> exchange(Link& link, BoundNode& node, const Request& request,
                                  const LinkTiming& timing);
  asio::awaitable<Waited> wait_reply(Link& link, const FrameSplitter& splitter,
                                     std::chrono::microseconds budget, const LinkTiming& timing);
  asio::awaitable<Reply> send_raw(Link& link, techno::CommandKind kind);
  void after_interrupt(techno::CommandKind kind);
  // answered_after_motion: a `P` answered later than any reply takes, so the controller held it
  // until the running motion had ended.
  void after_reply(BoundNode& node, const techno::Command& command,
                   const std::vector<int64_t>& values, Reply& reply, bool answered_after_motion);
  asio::awaitable<void> await_motion_position(Link& link, BoundNode& node, const Request& request,
                                              Reply& reply, const LinkTiming& timing);
  // An error character the controller sent on its own after acknowledging a lower-case motion
  // (`2`: limit or E-stop): read before the next request so it is neither lost nor taken for
  // that request's answer.
  asio::awaitable<void> collect_motion_error(Link& link, NodeState& state,
                                             const LinkTiming& timing);
  int64_t in_motion(BoundNode& node, const std::array<int64_t, 3>& xyz, bool at_rest);
  asio::awaitable<void> resync(Link& link, const LinkTiming& timing);
  void take_leading_motion_error(BoundNode& node, const Request& request, std::string_view frame,
                                 Reply& reply);
  asio::awaitable<void> take_optional_terminator(Link& link, NodeState& state,
                                                 std::string_view frame, Reply& reply,
                                                 const LinkTiming& timing);
  asio::awaitable<void> check_single_handshake(Link& link, const techno::Command& c, Reply& reply,
                                               const LinkTiming& timing);

  // The controllers on this line (bind_node), and their profiles merged by profile().
  std::vector<std::weak_ptr<BoundNode>> bound_;
  std::optional<techno::Profile> profile_;
  uint64_t interrupts_ = 0;  // stop and reset bytes sent on this line
  char last_interrupt_ = 0;
  int64_t pending_error_ = 0;    // an error character that followed a motion's acknowledge
  bool resync_ = false;          // a timeout or garbled reply: wait for a quiet line first
  bool writing_ = false;         // transact() is sending a command
  bool urgent_writing_ = false;  // send_urgent() is sending a raw byte
};

// The decision part of transact(): what a complete reply (or the bytes an idle gap ended) means
// for this request. Position replies carry X Y Z only; the family adds in_motion and units.
// fitted_axes (the model's) says which shorter position replies a controller may give.
Reply interpret_techno_reply(const Request& request, std::string_view frame, int fitted_axes = 3);

}  // namespace fieldgate
