#include "gateway/register_map/register_map_handler.hpp"

#include <algorithm>

#include "gateway/image/point_freshness.hpp"
#include "gateway/register_map/control_exception.hpp"
#include "gateway/register_map/device_identification.hpp"

namespace fieldgate {

using modbus::ExceptionCode;

namespace {
using Clock = std::chrono::steady_clock;

Table to_table(modbus::RegisterTable t) {
  return t == modbus::RegisterTable::holding_registers ? Table::holding_registers
                                                       : Table::input_registers;
}
Table to_table(modbus::BitTable t) {
  return t == modbus::BitTable::coils ? Table::coils : Table::discrete_inputs;
}
// While an action's step holds the line (a motion that answers at its end), nothing is polled,
// but the axes are known to move: the bit its done condition watches reads "not done".
int64_t held_line_view(const UnitMap& unit, const NodeImage& node, const RegisterEntry& e,
                       int64_t value) {
  if (!node.action.holding_line) return value;
  const ActionDef* action = unit.model->find_action(node.action.holding_code);
  if (!action || !action->done || !action->done->bit) return value;
  if (unit.model->points[static_cast<std::size_t>(e.index)].name != action->done->point)
    return value;
  const int64_t mask = int64_t{1} << *action->done->bit;
  return action->done->equals ? (value & ~mask) : (value | mask);
}

}  // namespace

RegisterMapHandler::RegisterMapHandler(std::shared_ptr<const LoadedConfig> config,
                                       std::size_t listener, ProcessImage& image,
                                       ActionRunner& actions, ControlService& control)
    : config_(std::move(config)),
      map_(config_->map_of(listener)),
      modbus_(config_->gateway.listener_modbus(listener)),
      image_(image),
      control_(control),
      profile_(image, actions, control, modbus_) {
  for (const auto& bus : config_->gateway.buses)
    for (const auto& node : bus.nodes) {
      const int index = static_cast<int>(nodes_.size());
      nodes_.push_back(&node);
      if (node.listener != listener) continue;  // profile units are per listener too
      for (const auto& [axis, unit] : node.axis_units)
        if (const auto* def = node.model->find_profile_axis(axis))
          profile_units_[unit] = {index, &node, node.model,
                                  static_cast<int>(def - node.model->profile_axes.data())};
    }
}

const ProfileUnit* RegisterMapHandler::profile_unit(uint8_t unit) const {
  const auto it = profile_units_.find(unit);
  return it == profile_units_.end() ? nullptr : &it->second;
}

std::optional<ExceptionCode> RegisterMapHandler::entry_value(const UnitMap& unit,
                                                             const RegisterEntry& e, SteadyTime now,
                                                             int64_t& value) const {
  const auto& node = image_.node(unit.node_index);
  switch (e.kind) {
    case RegisterEntry::Kind::point:
    case RegisterEntry::Kind::point_bit: {
      const auto& pv = node.points[static_cast<std::size_t>(e.index)];
      const bool offline = node.state != NodeState::online &&
                           !(node.state == NodeState::starting && node.carried_over);
      if (!pv.valid) return ExceptionCode::gateway_target_failed;
      if (offline) {
        if (modbus_.offline_reads == OfflineReads::exception)
          return ExceptionCode::gateway_target_failed;
        // last_value: the node's state (diagnostic block) tells that its values are old.
      } else if (!point_is_fresh(node, *unit.model, static_cast<std::size_t>(e.index), now)) {
        // Nothing tells a PLC that an online node's point stopped updating: never serve it.
        return ExceptionCode::gateway_target_failed;
      }
      value = held_line_view(unit, node, e, pv.value);
      value = e.kind == RegisterEntry::Kind::point ? value : ((value >> e.bit) & 1);
      return std::nullopt;
    }
    case RegisterEntry::Kind::setpoint:
      value = node.setpoints[static_cast<std::size_t>(e.index)];
      return std::nullopt;
    case RegisterEntry::Kind::action_command:
      value = node.action.code;
      return std::nullopt;
    case RegisterEntry::Kind::action_status:
      value = static_cast<uint16_t>(node.action.status);
      return std::nullopt;
    case RegisterEntry::Kind::action_error:
      value = node.action.error;
      return std::nullopt;
    case RegisterEntry::Kind::action_sequence:
      value = node.action.sequence;
      return std::nullopt;
    case RegisterEntry::Kind::diagnostic:
      value = image_.diagnostic(unit.node_index, static_cast<DiagnosticField>(e.index), now);
      return std::nullopt;
  }
  return ExceptionCode::server_device_failure;
}

modbus::ReadBitsResult RegisterMapHandler::read_bits(uint8_t unit_id, modbus::BitTable table,
                                                     uint16_t address, uint16_t count) {
  if (profile_unit(unit_id)) return ExceptionCode::illegal_data_address;
  const UnitMap* unit = unit_of(unit_id);
  if (!unit) return ExceptionCode::gateway_path_unavailable;
  std::vector<bool> bits;
  bits.reserve(count);
  const SteadyTime now = Clock::now();
  for (uint32_t a = address; a < static_cast<uint32_t>(address) + count; ++a) {
    const RegisterEntry* e = unit->find(to_table(table), static_cast<uint16_t>(a));
    if (!e) return ExceptionCode::illegal_data_address;
    int64_t value = 0;
    if (auto ex = entry_value(*unit, *e, now, value)) return *ex;
    bits.push_back(value != 0);
  }
  return bits;
}

modbus::DeviceIdentificationResult RegisterMapHandler::device_identification(uint8_t unit_id) {
  if (const auto* axis = profile_unit(unit_id)) unit_id = axis->node->unit_id;
  const UnitMap* unit = unit_of(unit_id);
  if (!unit) return ExceptionCode::gateway_path_unavailable;
  return identify(*unit, image_.node(unit->node_index));
}

modbus::ReadRegistersResult RegisterMapHandler::read_registers(uint8_t unit_id,
                                                               modbus::RegisterTable table,
                                                               uint16_t address, uint16_t count) {
  if (const auto* axis = profile_unit(unit_id))
    return profile_.read(*axis, table, address, count, map_.word_order());
  const UnitMap* unit = unit_of(unit_id);
  if (!unit) return ExceptionCode::gateway_path_unavailable;
  const WordOrder order = map_.word_order();
  std::vector<uint16_t> words;
  words.reserve(count);
  const SteadyTime now = Clock::now();
  uint32_t a = address;
  const uint32_t end = static_cast<uint32_t>(address) + count;
  while (a < end) {
    const RegisterEntry* e = unit->find(to_table(table), static_cast<uint16_t>(a));
    if (!e) return ExceptionCode::illegal_data_address;
    int64_t value = 0;
    if (auto ex = entry_value(*unit, *e, now, value)) return *ex;
    const auto encoded = to_registers(e->type, value, order);
    // A read may start or end inside a 32-bit value; it gets the words it covers.
    for (uint32_t w = a - e->address; w < e->count && a < end; ++w, ++a)
      words.push_back(encoded[w]);
  }
  return words;
}

asio::awaitable<modbus::WriteResult> RegisterMapHandler::write_registers(
    uint8_t unit_id, uint16_t address, std::span<const uint16_t> values) {
  const WordOrder order = map_.word_order();
  const auto& modbus_config = modbus_;
  if (const auto* axis = profile_unit(unit_id)) {
    if (modbus_config.read_only_holding || modbus_config.unit_read_only(unit_id))
      co_return ExceptionCode::illegal_function;
    const ProfileUnit target = *axis;
    co_return co_await profile_.write(target, address, values, order);
  }
  const UnitMap* unit = unit_of(unit_id);
  if (!unit) co_return ExceptionCode::gateway_path_unavailable;
  if (modbus_config.read_only_holding || modbus_config.unit_read_only(unit_id))
    co_return ExceptionCode::illegal_function;

  // The registers name the writes; the control service checks them all before any runs.
  const WritePolicy policy{true, modbus_config.writes_enabled};
  std::vector<ControlWrite> writes;
  std::optional<ExceptionCode> held;
  const uint32_t end = static_cast<uint32_t>(address) + values.size();
  for (uint32_t a = address; a < end;) {
    const RegisterEntry* e = unit->find(Table::holding_registers, static_cast<uint16_t>(a));
    if (!e || !e->writable) co_return ExceptionCode::illegal_data_address;
    if (e->address != a || e->address + e->count > end)
      co_return ExceptionCode::illegal_data_value;  // half of a 32-bit value
    const int64_t value = from_registers(e->type, values.subspan(a - address, e->count), order);
    if (!in_range(e->type, value)) co_return ExceptionCode::illegal_data_value;
    ControlWrite w{ControlWrite::Kind::point, unit->node_index, e->index, value};
    if (e->kind == RegisterEntry::Kind::setpoint)
      w.kind = ControlWrite::Kind::setpoint;
    else if (e->kind == RegisterEntry::Kind::action_command)
      w.kind = ControlWrite::Kind::action;
    else if (e->kind != RegisterEntry::Kind::point)
      co_return ExceptionCode::illegal_data_address;
    const ControlResult checked = control_.check(w, policy);
    // A held line answers busy only once every register passed the other checks.
    if (checked.status == ControlStatus::line_held)
      held = exception_for(checked.status);
    else if (!checked.ok())
      co_return exception_for(checked.status);
    writes.push_back(w);
    a += e->count;
  }
  if (held) co_return *held;
  for (const auto& w : writes) {
    const ControlResult result = co_await control_.apply(w);
    if (!result.ok()) co_return exception_for(result.status);
  }
  co_return modbus::WriteResult::success();
}

asio::awaitable<modbus::WriteResult> RegisterMapHandler::write_coils(uint8_t unit_id, uint16_t,
                                                                     std::vector<bool>) {
  if (profile_unit(unit_id)) co_return ExceptionCode::illegal_data_address;
  if (!unit_of(unit_id)) co_return ExceptionCode::gateway_path_unavailable;
  const auto& m = modbus_;
  if (m.read_only_coils || m.unit_read_only(unit_id)) co_return ExceptionCode::illegal_function;
  co_return ExceptionCode::illegal_data_address;
}

}  // namespace fieldgate
