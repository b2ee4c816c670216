#include "gateway/register_map/axis_profile_server.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>

#include "gateway/image/point_freshness.hpp"
#include "gateway/lifecycle/log.hpp"
#include "gateway/register_map/control_exception.hpp"

namespace fieldgate {

using modbus::ExceptionCode;
namespace ap = axis_profile;

namespace {

constexpr auto kFollowInterval = std::chrono::milliseconds(20);
// How long a command's completion waits for the profile's moving (or enabled) bit to agree with
// it (a jog that cannot move, e.g. standing on a limit, ends done after it).
constexpr auto kJogStartPatience = std::chrono::seconds(2);
// How long an axis may stand still away from its target after its actions ended before the
// command fails (a controller reporting its final steps a poll late).
constexpr auto kArrivalPatience = std::chrono::seconds(1);
// How long a command whose step got no reply waits for the controller's next answer, which shows
// whether it was reset (a card that lost power mid-move never acknowledges the move).
constexpr auto kResetEvidencePatience = std::chrono::seconds(2);
constexpr std::size_t kTarget = 0, kVelocity = 1, kAcceleration = 2, kDeceleration = 3;

int point_index(const Model& model, const std::string& name) {
  if (name.empty()) return -1;
  const PointDef* p = model.find_point(name);
  return p ? static_cast<int>(p - model.points.data()) : -1;
}

std::optional<int64_t> point_value(const Model& model, const NodeImage& node,
                                   const std::string& name) {
  const int i = point_index(model, name);
  if (i < 0) return std::nullopt;
  const auto& v = node.points[static_cast<std::size_t>(i)];
  if (!v.valid) return std::nullopt;
  return v.value;
}

bool status_bit(const Model& model, const NodeImage& node, const ProfileAxisDef& axis,
                StatusBit bit) {
  const auto it = axis.status.find(bit);
  if (it == axis.status.end()) return false;
  const StatusSource& s = it->second;
  if (s.constant) return *s.constant;
  const auto value = point_value(model, node, s.point);
  if (!value) return false;
  const int64_t observed = s.bit ? ((*value >> *s.bit) & 1) : *value;
  return (observed == s.value) != s.negate;
}

// Whether the point with index `i` (none: -1) was read after `since`.
bool read_since(const NodeImage& node, int i, std::chrono::steady_clock::time_point since) {
  if (i < 0) return false;
  const auto& v = node.points[static_cast<std::size_t>(i)];
  return v.valid && v.updated > since;
}

// Whether the point behind a status bit was read after `since` (a constant always is).
bool status_read_since(const Model& model, const NodeImage& node, const ProfileAxisDef& axis,
                       StatusBit bit, std::chrono::steady_clock::time_point since) {
  const auto it = axis.status.find(bit);
  if (it == axis.status.end() || it->second.constant) return true;
  const int i = point_index(model, it->second.point);
  return i < 0 || read_since(node, i, since);
}

// The profile values a command passes to the model, and from which register.
std::vector<std::pair<ProfileSetpoint, std::size_t>> inputs_of(ProfileCommand c) {
  switch (c) {
    case ProfileCommand::move_absolute:
      return {{ProfileSetpoint::target, kTarget},
              {ProfileSetpoint::velocity, kVelocity},
              {ProfileSetpoint::acceleration, kAcceleration},
              {ProfileSetpoint::deceleration, kDeceleration}};
    case ProfileCommand::move_relative:
      return {{ProfileSetpoint::distance, kTarget},
              {ProfileSetpoint::velocity, kVelocity},
              {ProfileSetpoint::acceleration, kAcceleration},
              {ProfileSetpoint::deceleration, kDeceleration}};
    case ProfileCommand::jog_positive:
    case ProfileCommand::jog_negative:
      return {{ProfileSetpoint::jog_velocity, kVelocity},
              {ProfileSetpoint::acceleration, kAcceleration},
              {ProfileSetpoint::deceleration, kDeceleration}};
    case ProfileCommand::home:
      return {{ProfileSetpoint::home_velocity, kVelocity}};
    case ProfileCommand::stop:
    case ProfileCommand::halt:
      return {{ProfileSetpoint::deceleration, kDeceleration}};
    default:
      return {};
  }
}

std::optional<int64_t> none_value(const Model& model, const std::string& name) {
  if (const SetpointDef* s = model.find_setpoint(name)) return s->none;
  if (const PointDef* p = model.find_point(name)) return p->none;
  return std::nullopt;
}

bool is_speed(ProfileSetpoint which) {
  return which == ProfileSetpoint::velocity || which == ProfileSetpoint::jog_velocity ||
         which == ProfileSetpoint::home_velocity;
}

// Whether a point was read after `since`.
bool read_since(const Model& model, const NodeImage& node, const std::string& name,
                std::chrono::steady_clock::time_point since) {
  return read_since(node, point_index(model, name), since);
}

// Why the controller is known to have reset since the command was accepted, if it has: the
// gateway saw it (a boot-up, a sign-on), or the model's reset count changed.
std::optional<std::string> reset_since_accepted(const Model& model, const NodeImage& node,
                                                const ProfileAxisDef& axis,
                                                const ProfileAxisRuntime& rt) {
  if (node.controller_resets != rt.resets) return "seen by the gateway";
  if (axis.reset_count.empty() || !read_since(model, node, axis.reset_count, rt.accepted))
    return std::nullopt;
  // Unknown when the command was accepted (the counter not read yet since the start): the first
  // reading is the baseline, and follow() keeps it.
  const auto count = point_value(model, node, axis.reset_count);
  if (count && rt.reset_count && count != rt.reset_count)
    return fmt::format("{} went from {} to {}", axis.reset_count,
                       rt.reset_count ? std::to_string(*rt.reset_count) : "unknown", *count);
  return std::nullopt;
}

enum class Arrival { yes, not_yet, no };

// Whether a move stands at its target, or a home is homed, on readings after `since`.
Arrival arrival(const Model& model, const NodeImage& node, const ProfileAxisDef& axis,
                const ProfileAxisRuntime& rt, std::chrono::steady_clock::time_point since) {
  if (rt.command == ProfileCommand::home) {
    const auto it = axis.status.find(StatusBit::homed);
    if (it == axis.status.end() || it->second.constant) return Arrival::yes;
    if (!status_read_since(model, node, axis, StatusBit::homed, since)) return Arrival::not_yet;
    return status_bit(model, node, axis, StatusBit::homed) ? Arrival::yes : Arrival::no;
  }
  if (!rt.target) return Arrival::yes;
  if (!read_since(model, node, axis.position, since)) return Arrival::not_yet;
  const auto position = point_value(model, node, axis.position);
  if (!position) return Arrival::not_yet;
  const int64_t off = *position > *rt.target ? *position - *rt.target : *rt.target - *position;
  return off <= axis.position_tolerance ? Arrival::yes : Arrival::no;
}

void finish_with_error(ProfileAxisRuntime& rt, uint16_t code) {
  rt.status = CommandStatus::error;
  rt.command_error = code;
  rt.error_latched = true;
  rt.error_id = code;
}

// The controller did not answer a step: a power cycle may have cut it off, which only its next
// answer shows.
bool is_silence(uint16_t action_error) {
  return action_error == kActionErrorNoReply || action_error == kActionErrorUnreachable ||
         action_error == kActionErrorGarbled;
}

// Ends the command failed. A failure that a reset of the controller explains (a Techno card that
// lost its axes definition refuses the move with 4) ends with the reset's own code.
void fail_command(const ProfileUnit& unit, const NodeImage& node, ProfileAxisRuntime& rt,
                  uint16_t code) {
  const Model& model = *unit.model;
  const auto& axis = model.profile_axes[static_cast<std::size_t>(unit.axis)];
  if (rt.command != ProfileCommand::reset) {
    if (const auto why = reset_since_accepted(model, node, axis, rt)) {
      log::warning("unit {} axis {}: {} failed: the controller reset while it ran ({})",
                   unit.node->name, axis.name, to_string(rt.command), *why);
      code = kActionErrorControllerReset;
    }
  }
  finish_with_error(rt, code);
}

}  // namespace

AxisProfileServer::AxisProfileServer(ProcessImage& image, ActionRunner& actions,
                                     ControlService& control, const ModbusConfig& modbus)
    : image_(image), actions_(actions), control_(control), modbus_(modbus) {}

AxisProfileServer::~AxisProfileServer() {
  *alive_ = false;
}

ProfileAxisRuntime& AxisProfileServer::runtime(const ProfileUnit& unit) {
  auto& node = image_.node(unit.node_index);
  if (node.profile_axes.size() < unit.model->profile_axes.size())
    node.profile_axes.resize(unit.model->profile_axes.size());
  auto& rt = node.profile_axes[static_cast<std::size_t>(unit.axis)];
  if (!rt.action) rt.action = std::make_shared<ActionState>();
  if (!rt.initialised) {
    // The model's own defaults (or the node's configured setpoints), so a PLC that never writes
    // a velocity still moves at a sane one.
    const auto& axis = unit.model->profile_axes[static_cast<std::size_t>(unit.axis)];
    const auto from = [&](ProfileSetpoint p, std::size_t slot) {
      const auto it = axis.setpoints.find(p);
      if (it == axis.setpoints.end()) return;
      const SetpointDef* s = unit.model->find_setpoint(it->second);
      if (!s) {
        // A controller register: its value as last polled, if it was.
        if (const auto v = point_value(*unit.model, node, it->second)) rt.setpoints[slot] = *v;
        return;
      }
      const auto index = static_cast<std::size_t>(s - unit.model->setpoints.data());
      if (index < node.setpoints.size()) rt.setpoints[slot] = node.setpoints[index];
    };
    from(ProfileSetpoint::velocity, kVelocity);
    from(ProfileSetpoint::acceleration, kAcceleration);
    from(ProfileSetpoint::deceleration, kDeceleration);
    rt.initialised = node.state == NodeState::online;  // again once the registers are polled
  }
  return rt;
}

AxisObservation AxisProfileServer::observe(const ProfileUnit& unit,
                                           const ProfileAxisRuntime& rt) const {
  return observe_axis(unit, image_.node(unit.node_index), rt);
}

AxisObservation observe_axis(const ProfileUnit& unit, const NodeImage& node,
                             const ProfileAxisRuntime& rt) {
  const Model& model = *unit.model;
  const auto& axis = model.profile_axes[static_cast<std::size_t>(unit.axis)];
  AxisObservation o;
  o.enabled = status_bit(model, node, axis, StatusBit::enabled);
  // While a step holds the line (a motion answered at its end) nothing is polled: it moves, if
  // the step is this axis's or the native layout's (not another profile axis's).
  const bool held_by_an_axis =
      std::any_of(node.profile_axes.begin(), node.profile_axes.end(),
                  [](const ProfileAxisRuntime& a) { return a.action && a.action->holding_line; });
  o.moving = status_bit(model, node, axis, StatusBit::moving) ||
             (rt.action && rt.action->holding_line) ||
             (node.action.holding_line && !held_by_an_axis);
  o.error = status_bit(model, node, axis, StatusBit::error);
  o.error_latched = rt.error_latched;
  o.command = rt.command;
  o.status = rt.status;
  return o;
}

AxisReading read_axis(const ProfileUnit& unit, const NodeImage& node,
                      const ProfileAxisRuntime& rt) {
  const Model& model = *unit.model;
  const auto& axis = model.profile_axes[static_cast<std::size_t>(unit.axis)];
  AxisReading r;
  r.position = point_value(model, node, axis.position);
  r.velocity = point_value(model, node, axis.velocity);
  r.online = node.state == NodeState::online;
  const AxisObservation o = observe_axis(unit, node, rt);
  r.state = derive_state(o);
  const auto set = [&](StatusBit b, bool on) {
    if (on) r.status_word |= static_cast<uint16_t>(1u << static_cast<unsigned>(b));
  };
  set(StatusBit::enabled, o.enabled);
  set(StatusBit::homed, status_bit(model, node, axis, StatusBit::homed));
  set(StatusBit::moving, o.moving);
  set(StatusBit::in_position, o.enabled && !o.moving && rt.status != CommandStatus::busy &&
                                  rt.status != CommandStatus::error);
  set(StatusBit::error, o.error);
  set(StatusBit::limit_positive, status_bit(model, node, axis, StatusBit::limit_positive));
  set(StatusBit::limit_negative, status_bit(model, node, axis, StatusBit::limit_negative));
  set(StatusBit::warning, status_bit(model, node, axis, StatusBit::warning));
  set(StatusBit::velocity_reported, r.velocity.has_value());
  set(StatusBit::online, r.online);
  r.error_id = rt.error_latched ? rt.error_id : 0;
  if (o.error && r.error_id == 0) {
    const auto code = point_value(model, node, axis.error_code);
    r.error_id = code && *code != 0 ? static_cast<uint16_t>(*code) : kProfileErrorDeviceFault;
  }
  r.sequence = rt.sequence;
  r.command = rt.command;
  r.status = rt.status;
  r.command_error = rt.command_error;
  r.supported = axis.supported_mask();
  return r;
}

// Whether the page may be served: its position is fresh (not failing its polls, not older than
// its bound) and the points behind its state were read at least once, so that no state is
// derived from a status never seen.
bool axis_readings_fresh(const ProfileUnit& unit, const NodeImage& node) {
  const Model& model = *unit.model;
  const auto& axis = model.profile_axes[static_cast<std::size_t>(unit.axis)];
  const auto now = std::chrono::steady_clock::now();
  const int position = point_index(model, axis.position);
  if (position < 0 || !point_is_fresh(node, model, static_cast<std::size_t>(position), now))
    return false;
  for (const auto& [bit, source] : axis.status) {
    if (source.constant) continue;
    const int i = point_index(model, source.point);
    if (i >= 0 && !node.points[static_cast<std::size_t>(i)].valid) return false;
  }
  return true;
}

modbus::ReadRegistersResult AxisProfileServer::read(const ProfileUnit& unit,
                                                    modbus::RegisterTable table, uint16_t address,
                                                    uint16_t count, WordOrder order) {
  const bool holding = table == modbus::RegisterTable::holding_registers;
  const uint32_t size = holding ? ap::holding_count : ap::input_count;
  if (static_cast<uint32_t>(address) + count > size) return ExceptionCode::illegal_data_address;
  auto& rt = runtime(unit);
  const auto& node = image_.node(unit.node_index);
  std::vector<uint16_t> page(size, 0);
  const auto put32 = [&](uint16_t at, int64_t v) {
    const auto words = to_registers(ValueType::int32, v, order);
    page[at] = words[0];
    page[at + 1u] = words[1];
  };
  if (holding) {
    for (std::size_t i = 0; i < 4; ++i) put32(static_cast<uint16_t>(2 * i), rt.setpoints[i]);
    page[ap::command_code] = static_cast<uint16_t>(rt.command);
    page[ap::sequence_number] = rt.sequence;
  } else {
    const AxisReading r = read_axis(unit, node, rt);
    if (!r.position || !axis_readings_fresh(unit, node))
      return ExceptionCode::gateway_target_failed;
    if (!r.online && modbus_.offline_reads == OfflineReads::exception)
      return ExceptionCode::gateway_target_failed;
    put32(ap::actual_position, *r.position);
    put32(ap::actual_velocity, r.velocity.value_or(0));
    page[ap::status_word] = r.status_word;
    page[ap::plcopen_state] = static_cast<uint16_t>(r.state);
    page[ap::error_id] = r.error_id;
    page[ap::sequence_echo] = r.sequence;
    page[ap::command_status] = static_cast<uint16_t>(r.status);
    page[ap::command_echo] = static_cast<uint16_t>(r.command);
    page[ap::command_error] = r.command_error;
    page[ap::supported_commands] = r.supported;
  }
  return std::vector<uint16_t>(page.begin() + address, page.begin() + address + count);
}

asio::awaitable<modbus::WriteResult> AxisProfileServer::write(ProfileUnit unit, uint16_t address,
                                                              std::span<const uint16_t> values,
                                                              WordOrder order) {
  const uint32_t end = static_cast<uint32_t>(address) + values.size();
  if (end > ap::holding_count) co_return ExceptionCode::illegal_data_address;
  // Half of a 32-bit setpoint, or of the command/sequence pair.
  if (address % 2 != 0 || end % 2 != 0) co_return ExceptionCode::illegal_data_value;
  auto& rt = runtime(unit);
  for (uint32_t a = address; a < end && a < ap::command_code; a += 2) {
    const int64_t v = from_registers(ValueType::int32, values.subspan(a - address, 2), order);
    rt.setpoints[a / 2] = v;
  }
  if (end <= ap::command_code) co_return modbus::WriteResult::success();
  const uint16_t code = values[ap::command_code - address];
  const uint16_t sequence = values[ap::sequence_number - address];
  if (code == 0 || code >= kProfileCommandCount || sequence == 0)
    co_return ExceptionCode::illegal_data_value;
  if (sequence == rt.sequence) co_return modbus::WriteResult::success();  // a repeat: ignored
  const ProfileUnit u = unit;
  co_return co_await command(u, static_cast<ProfileCommand>(code), sequence);
}

asio::awaitable<modbus::WriteResult> AxisProfileServer::command(ProfileUnit unit,
                                                                ProfileCommand cmd,
                                                                uint16_t sequence) {
  const Model& model = *unit.model;
  const auto& axis = model.profile_axes[static_cast<std::size_t>(unit.axis)];
  if (!axis.supports(cmd)) co_return exception_for(ControlStatus::not_supported);
  auto& node = image_.node(unit.node_index);
  auto& rt = runtime(unit);
  const auto& action_names = axis.commands.at(cmd);
  const ActionDef* first = action_names.empty() ? nullptr : model.find_action(action_names.front());
  const WritePolicy policy{true, modbus_.writes_enabled};
  if (const auto allowed = control_.check_command(unit.node_index, first, policy); !allowed.ok())
    co_return exception_for(allowed.status);
  // The values this command passes, checked against the model's and the node's limits. They go
  // into the command's own arguments: no other axis's command, nor a later write, changes them.
  ActionArguments arguments{node.setpoints, {}, {}};
  std::vector<ControlWrite> point_writes;
  for (const auto& [which, slot] : inputs_of(cmd)) {
    const auto it = axis.setpoints.find(which);
    if (it == axis.setpoints.end()) continue;
    const SetpointDef* s = model.find_setpoint(it->second);
    int64_t v = rt.setpoints[slot];
    if (which == ProfileSetpoint::jog_velocity || which == ProfileSetpoint::home_velocity)
      v = v < 0 ? -v : v;
    if (const auto checked = control_.check_value(unit.node_index, it->second, v); !checked.ok())
      co_return exception_for(checked.status);
    if (const auto none = none_value(model, it->second); none && *none == v && is_speed(which)) {
      log::warning(
          "unit {} axis {}: {} refused: {} {} means 'none' to this controller ({}); "
          "write the velocity (holding {}) first",
          unit.node->name, axis.name, to_string(cmd), it->second, v, model.name, ap::velocity);
      co_return ExceptionCode::illegal_data_value;
    }
    if (s)
      arguments.setpoints[static_cast<std::size_t>(s - model.setpoints.data())] = v;
    else
      point_writes.push_back(
          {ControlWrite::Kind::point, unit.node_index, point_index(model, it->second), v});
  }
  for (const auto& [name, value] : axis.fixed)
    arguments
        .setpoints[static_cast<std::size_t>(model.find_setpoint(name) - model.setpoints.data())] =
        value;
  for (const auto& [name, point] : axis.hold) {
    // Read when the action gets the node's turn, after any action before it on the node.
    if (!point_value(model, node, point)) co_return exception_for(ControlStatus::value_unknown);
    arguments.hold.emplace_back(
        static_cast<std::size_t>(model.find_setpoint(name) - model.setpoints.data()),
        static_cast<std::size_t>(point_index(model, point)));
  }
  // Where a move must end: the target, or the distance from where the axis stands still.
  std::optional<int64_t> proof_target;
  if (cmd == ProfileCommand::move_absolute && axis.setpoints.count(ProfileSetpoint::target)) {
    proof_target = rt.setpoints[kTarget];
  } else if (cmd == ProfileCommand::move_relative &&
             axis.setpoints.count(ProfileSetpoint::distance)) {
    const auto from = point_value(model, node, axis.position);
    if (from && !observe(unit, rt).moving) proof_target = *from + rt.setpoints[kTarget];
  }

  const PlcopenState state = derive_state(observe(unit, rt));
  const uint64_t generation = ++rt.generation;
  rt.sequence = sequence;
  rt.command = cmd;
  rt.command_error = 0;
  if (const auto refused = refusal(state, cmd)) {
    rt.status = CommandStatus::error;
    rt.command_error = *refused;
    log::info("unit {} axis {}: {} refused in state {}", unit.node->name, axis.name, to_string(cmd),
              to_string(state));
    co_return modbus::WriteResult::success();
  }
  if (action_names.empty() || (cmd == ProfileCommand::reset && axis.reset_only_in_error_stop &&
                               state != PlcopenState::error_stop)) {
    // A reset of a controller that has nothing to reset, or of an axis that is not in ErrorStop
    // where the model's reset acts on faults only: it clears the profile's own latch.
    rt.status = CommandStatus::done;
    rt.error_latched = false;
    rt.error_id = 0;
    co_return modbus::WriteResult::success();
  }
  abort_shared_stops(unit, cmd);
  rt.status = CommandStatus::busy;
  rt.target = proof_target;
  rt.resets = node.controller_resets;
  rt.reset_count = point_value(model, node, axis.reset_count);
  rt.accepted = std::chrono::steady_clock::now();
  const auto executor = co_await asio::this_coro::executor;
  auto alive = alive_;
  if (ActionRunner::takes_turn(*first) && node.turn->taken) {
    // Another command of this node (another axis's) is on the line: this one waits for its turn,
    // answered now with busy; how it goes shows in command_status.
    log::debug("unit {} axis {}: {} queued behind another command of the node", unit.node->name,
               axis.name, to_string(cmd));
    asio::co_spawn(
        executor,
        run_command(unit, generation, std::move(arguments), std::move(point_writes), first, alive),
        asio::detached);
    co_return modbus::WriteResult::success();
  }
  co_return co_await run_command(unit, generation, std::move(arguments), std::move(point_writes),
                                 first, alive);
}

asio::awaitable<modbus::WriteResult> AxisProfileServer::run_command(
    ProfileUnit unit, uint64_t generation, ActionArguments arguments,
    std::vector<ControlWrite> point_writes, const ActionDef* first, std::shared_ptr<bool> alive) {
  const auto superseded = [&] { return !*alive || runtime(unit).generation != generation; };
  // Point writes (a speed register) go out in the node's turn with the action's steps, so that
  // another axis's command cannot write its own between them.
  if (!point_writes.empty() && ActionRunner::takes_turn(*first)) {
    arguments.turn = co_await actions_.take_turn(unit.node_index);
    if (superseded()) co_return modbus::WriteResult::success();
  }
  {
    auto& rt = runtime(unit);
    rt.arguments = arguments;
    rt.arguments.turn.reset();
  }
  for (const auto& write : point_writes) {
    const ControlResult written = co_await control_.apply(write);
    if (superseded()) co_return modbus::WriteResult::success();
    if (!written.ok()) {
      fail_command(unit, image_.node(unit.node_index), runtime(unit),
                   written.status == ControlStatus::device_error
                       ? static_cast<uint16_t>(written.device_code)
                       : kActionErrorNoReply);
      co_return exception_for(written.status);
    }
  }
  const auto slot = runtime(unit).action;
  const uint64_t action_generation = slot->generation + 1;
  const ControlResult started =
      co_await control_.start_action(unit.node_index, *first, slot, std::move(arguments));
  if (superseded()) co_return modbus::WriteResult::success();
  if (!started.ok() && slot->generation == action_generation && is_silence(slot->error)) {
    // The write is answered now; follow() ends the command once the controller's next answer
    // shows whether a reset silenced it.
    const auto executor = co_await asio::this_coro::executor;
    asio::co_spawn(executor, follow(unit, generation, action_generation, 0, alive), asio::detached);
    co_return exception_for(started.status);
  }
  if (!started.ok()) {
    fail_command(unit, image_.node(unit.node_index), runtime(unit), slot->error);
    co_return exception_for(started.status);
  }
  const auto executor = co_await asio::this_coro::executor;
  asio::co_spawn(executor, follow(unit, generation, action_generation, 0, alive), asio::detached);
  co_return modbus::WriteResult::success();
}

// A stop or halt that the model gives the same action on other axes of the node (Centent Q,
// Whedco HT stop both axes of the unit) stops those axes too: their running commands end
// aborted. Any other command of one axis leaves the other axes' commands alone.
void AxisProfileServer::abort_shared_stops(const ProfileUnit& unit, ProfileCommand cmd) {
  if (cmd != ProfileCommand::stop && cmd != ProfileCommand::halt) return;
  const auto& axes = unit.model->profile_axes;
  const auto& names = axes[static_cast<std::size_t>(unit.axis)].commands.at(cmd);
  auto& node = image_.node(unit.node_index);
  for (std::size_t other = 0; other < axes.size() && other < node.profile_axes.size(); ++other) {
    if (static_cast<int>(other) == unit.axis) continue;
    auto& rt = node.profile_axes[other];
    // A running stop or halt of that axis still ends as it should: the axis stands still.
    if (rt.status != CommandStatus::busy || rt.command == ProfileCommand::stop ||
        rt.command == ProfileCommand::halt)
      continue;
    const auto shares = [&](ProfileCommand c) {
      const auto it = axes[other].commands.find(c);
      return it != axes[other].commands.end() && it->second == names;
    };
    if (!shares(ProfileCommand::stop) && !shares(ProfileCommand::halt)) continue;
    ++rt.generation;  // its follow-up ends here
    rt.status = CommandStatus::aborted;
  }
}

// Waits for each action of the command to complete and starts the next; ends the command in
// done, error (the axis goes to ErrorStop) or aborted (another command of the axis took over).
// A move or home is done only on the device's own word after this command: a position read
// after its actions ended at the target (moves), the homed bit set (homes, where the model
// maps one), and no reset of the controller since the command was accepted.
asio::awaitable<void> AxisProfileServer::follow(ProfileUnit unit, uint64_t generation,
                                                uint64_t action_generation, std::size_t step,
                                                std::shared_ptr<bool> alive) {
  const auto executor = co_await asio::this_coro::executor;
  asio::steady_timer timer(executor);
  std::optional<std::chrono::steady_clock::time_point> actions_ended;
  std::optional<std::chrono::steady_clock::time_point> off_target_since;
  std::optional<std::chrono::steady_clock::time_point> silent_since;
  for (;;) {
    timer.expires_after(kFollowInterval);
    co_await timer.async_wait(asio::as_tuple(asio::use_awaitable));
    if (!*alive) co_return;
    auto& rt = runtime(unit);
    if (rt.generation != generation) co_return;
    const auto slot = rt.action;
    if (slot->generation != action_generation) {
      rt.status = CommandStatus::aborted;
      co_return;
    }
    const auto& node = image_.node(unit.node_index);
    const Model& model = *unit.model;
    const auto& axis = model.profile_axes[static_cast<std::size_t>(unit.axis)];
    if (rt.command != ProfileCommand::reset && reset_since_accepted(model, node, axis, rt)) {
      fail_command(unit, node, rt, kActionErrorControllerReset);
      co_return;
    }
    if (!rt.reset_count && !axis.reset_count.empty())
      rt.reset_count = point_value(model, node, axis.reset_count);
    if (slot->status == ActionStatus::busy) continue;
    if (slot->status == ActionStatus::error) {
      // Silence may be a reset that the controller's next answer shows (checked above on every
      // turn): until the axis is read again, or for a moment if it is not, the silence waits.
      if (is_silence(slot->error)) {
        const auto now = std::chrono::steady_clock::now();
        if (!silent_since) silent_since = now;
        if (now < *silent_since + kResetEvidencePatience &&
            !read_since(model, node, axis.position, *silent_since))
          continue;
      }
      fail_command(unit, node, rt, slot->error);
      co_return;
    }
    const auto& names = axis.commands.at(rt.command);
    if (!actions_ended && ++step < names.size()) {
      const ActionDef* next = model.find_action(names[step]);
      action_generation = slot->generation + 1;
      const Reply reply =
          co_await actions_.start(unit.node_index, unit.model, *next, slot, rt.arguments);
      if (!*alive) co_return;
      auto& again = runtime(unit);
      if (again.generation != generation) co_return;
      if (reply.status != Reply::Status::ok) {
        fail_command(unit, image_.node(unit.node_index), again, slot->error);
        co_return;
      }
      continue;
    }
    const auto now = std::chrono::steady_clock::now();
    if (!actions_ended) actions_ended = now;
    // A jog is done once the drive runs: wait (briefly) until the polls show the motion, so the
    // state goes from busy ContinuousMotion straight on to moving ContinuousMotion.
    // Likewise a move, home, stop or halt is done only once the profile's own moving bit (which
    // may come from another point than the action's done condition) shows standstill.
    const bool jog =
        rt.command == ProfileCommand::jog_positive || rt.command == ProfileCommand::jog_negative;
    // A power on (off) is done only once the profile's enabled bit shows it: a master that
    // commands a home as soon as power_on is done must not find the axis still Disabled.
    const bool power =
        rt.command == ProfileCommand::power_on || rt.command == ProfileCommand::power_off;
    const bool motion = !power && rt.command != ProfileCommand::reset;
    const AxisObservation seen = observe(unit, rt);
    if ((motion && seen.moving != jog) ||
        (power && seen.enabled != (rt.command == ProfileCommand::power_on))) {
      // Patience runs out only against a status read after the actions ended: a poll slower
      // than the patience (a unit at 1200 baud) would otherwise end a jog done, and the axis
      // Standstill, on a status read before the jog began.
      const bool read_after = status_read_since(
          model, node, axis, power ? StatusBit::enabled : StatusBit::moving, *actions_ended);
      if (now < *actions_ended + kJogStartPatience || !read_after) continue;
      if (!jog && !power) continue;  // still moving: a move or stop is done at standstill only
    }
    if (const auto proof = arrival(model, node, axis, rt, *actions_ended); proof != Arrival::yes) {
      if (proof == Arrival::not_yet) continue;
      // Standing still away from the target (or not homed) on a reading after the actions
      // ended: give the controller a moment to report its last steps, then it did not arrive.
      if (!off_target_since) off_target_since = now;
      if (now < *off_target_since + kArrivalPatience ||
          !read_since(model, node, axis.position, *off_target_since + kArrivalPatience))
        continue;
      const auto position = point_value(model, node, axis.position);
      log::warning("unit {} axis {}: {} failed: the axis stands at {} (target {}, tolerance {}){}",
                   unit.node->name, axis.name, to_string(rt.command),
                   position ? std::to_string(*position) : "unknown",
                   rt.target ? std::to_string(*rt.target) : "none", axis.position_tolerance,
                   rt.command == ProfileCommand::home ? ", not homed" : "");
      finish_with_error(rt, kProfileErrorNotAtTarget);
      co_return;
    }
    rt.status = CommandStatus::done;
    if (rt.command == ProfileCommand::reset) {
      rt.error_latched = false;
      rt.error_id = 0;
    }
    co_return;
  }
}

}  // namespace fieldgate
