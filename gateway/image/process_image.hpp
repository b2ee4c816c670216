#pragma once

#include <boost/asio/steady_timer.hpp>

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gateway/image/axis_profile_state.hpp"
#include "gateway/image/node_turn.hpp"
#include "mapping/node_diagnostics.hpp"

namespace fieldgate {

using SteadyTime = std::chrono::steady_clock::time_point;

struct PointValue {
  int64_t value = 0;
  SteadyTime updated{};
  bool valid = false;  // a good reply has been seen
  // Polls of the point that failed (timeout, garbled, refused, unreachable): in a row since its
  // last good value (a value stored with {value, time, true} clears it), and in all. A bus keeps
  // the total across a good value with store_polled_value().
  uint32_t failed_polls = 0;
  uint64_t failed_polls_total = 0;
  // How long the bus took between its last two good polls of the point, and when the last one
  // was: a line that cannot keep up with the configured periods (the poll budget's "periods
  // will stretch") polls a point less often, and its age bound stretches with it. A confirmed
  // write refreshes the value, not these.
  std::chrono::microseconds interval{0};
  SteadyTime polled{};
};

// A polled value arrived: fresh again, its failure total kept.
inline void store_polled_value(PointValue& point, int64_t value, SteadyTime at) {
  const auto interval =
      point.polled != SteadyTime{} && at > point.polled
          ? std::chrono::duration_cast<std::chrono::microseconds>(at - point.polled)
          : std::chrono::microseconds{0};
  point = {value, at, true, 0, point.failed_polls_total, interval, at};
}

// The controller confirmed a write of the point: its value until the next poll.
inline void store_confirmed_value(PointValue& point, int64_t value, SteadyTime at) {
  point.value = value;
  point.updated = at;
  point.valid = true;
  point.failed_polls = 0;
}

// When a polled point's value is stale, so never served (gateway/image/point_freshness.hpp): its
// last `failed_polls` polls failed, or it is older than `periods` of its poll period and
// `at_least`. Set by the bus from its `timing: stale_after:` (docs/configuration.md).
struct FreshnessPolicy {
  uint32_t failed_polls = 3;  // 0: failures alone never make a point stale
  uint32_t periods = 4;       // 0: no age bound
  std::chrono::microseconds at_least{std::chrono::seconds(2)};
  // By model point index: the period the bus polls it at (the node's poll: overrides applied);
  // empty, or 0 for a point: the model's poll class period.
  std::vector<std::chrono::microseconds> poll_periods;
};

// faulted: the node answers, but refuses every poll (e.g. a wrong axis letter): its values are
// never fresh, so it is not online.
enum class NodeState : uint16_t { starting = 0, online = 1, offline = 2, faulted = 3 };
std::string_view to_string(NodeState state);

struct NodeCounters {
  uint64_t transactions = 0;
  uint64_t timeouts = 0;
  uint64_t unreachable = 0;  // a forwarding device answered that the node is not reachable
  uint64_t errors = 0;
  uint64_t retries = 0;
  uint32_t consecutive_timeouts = 0;
  // Commands (writes, action steps) that got no valid reply: sent, so they may have run. Also
  // counted in timeouts or errors; a PLC must not assume either outcome.
  uint64_t unknown_writes = 0;
  // Polls that failed (PointValue::failed_polls counts them per point); a probe of an offline
  // node is not counted.
  uint64_t failed_polls = 0;
  int64_t last_device_error = 0;
  std::string last_error_text;
  SteadyTime last_good{};
  bool ever_good = false;
};

struct ActionState {
  ActionStatus status = ActionStatus::idle;
  uint16_t code = 0;
  uint16_t error = 0;
  uint16_t sequence = 0;
  uint64_t generation = 0;  // a newer action supersedes the completion watch of an older one
  // A step confirmed early (confirm_after) is still waiting for its reply, so its bus is held
  // until the motion ends: writes that need the bus answer 0x06 at once (register map).
  bool holding_line = false;
  uint16_t holding_code = 0;  // the action whose step holds the line (the node's register only)
};

// Action errors that are not device codes.
// No completion within the action's timeout.
inline constexpr uint16_t kActionErrorTimeout = 0xffff;
inline constexpr uint16_t kActionErrorFailedCondition = 0xfffe;
inline constexpr uint16_t kActionErrorUnreachable = 0xfffd;
// A step got no reply: it may have run; never retried.
inline constexpr uint16_t kActionErrorNoReply = 0xfffc;
// The reply that should have ended a step arrived corrupted (not a valid reply to it): it may
// have run; never retried. Told apart from no reply at all.
inline constexpr uint16_t kActionErrorGarbled = 0xfffb;
// kActionErrorControllerReset (0xfffa, mapping/axis_profile.hpp): the controller reset while
// the action ran.

struct NodeImage {
  std::vector<PointValue> points;  // by model point index
  std::vector<bool> polled;        // by model point index: the bus polls it (empty: unknown)
  // Action watches waiting for fresh values; the bus wakes them after each update. Kept here,
  // not in a runner, so a watch started before a reload is still woken after it.
  std::vector<boost::asio::steady_timer*> waiters;
  std::vector<int64_t> setpoints;  // by model setpoint index
  NodeCounters counters;
  NodeState state = NodeState::starting;
  // Resets, power cycles, boot-ups and sign-ons of the controller that the gateway saw (from its
  // family, a CANopen boot-up or the model's reset indication): a command running across one
  // never ends done.
  uint64_t controller_resets = 0;
  std::shared_ptr<NodeTurnState> turn = std::make_shared<NodeTurnState>();
  // The values were read by the bus a reload replaced (the node itself unchanged): served, with
  // their age, while this node is still starting on the new bus.
  bool carried_over = false;
  ActionState action;
  FreshnessPolicy freshness;
  std::vector<ProfileAxisRuntime> profile_axes;  // by the model's profile axis index
};

// The latest value of every point with its time and quality, plus per-node diagnostics,
// indexed by the gateway's node number. The node images belong to the buses (a reload keeps an
// unchanged bus and its images). Only the io_context thread touches it: no locking.
class ProcessImage {
 public:
  ProcessImage() = default;
  explicit ProcessImage(std::vector<std::shared_ptr<NodeImage>> nodes) : nodes_(std::move(nodes)) {}
  NodeImage& node(int index) { return *nodes_.at(static_cast<std::size_t>(index)); }
  const NodeImage& node(int index) const { return *nodes_.at(static_cast<std::size_t>(index)); }
  std::size_t size() const { return nodes_.size(); }

  // The value of a diagnostic field as the Modbus map presents it.
  int64_t diagnostic(int index, DiagnosticField field, SteadyTime now) const;

 private:
  std::vector<std::shared_ptr<NodeImage>> nodes_;
};

}  // namespace fieldgate
