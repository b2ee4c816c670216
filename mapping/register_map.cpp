#include "mapping/register_map.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fieldgate {

std::string_view to_string(Table table) {
  switch (table) {
    case Table::coils:
      return "coils";
    case Table::discrete_inputs:
      return "discrete inputs";
    case Table::input_registers:
      return "input registers";
    case Table::holding_registers:
      return "holding registers";
  }
  return "?";
}

const RegisterEntry* UnitMap::find(Table table, uint16_t address) const {
  const auto& entries = tables[static_cast<int>(table)];
  auto it = std::upper_bound(entries.begin(), entries.end(), address,
                             [](uint16_t a, const RegisterEntry& e) { return a < e.address; });
  if (it == entries.begin()) return nullptr;
  --it;
  if (address < it->address + it->count) return &*it;
  return nullptr;
}

namespace {

struct DiagnosticLayout {
  DiagnosticField field;
  const char* name;
  ValueType type;
  const char* description;
};

constexpr DiagnosticLayout kDiagnostics[] = {
    {DiagnosticField::online, "diag.online", ValueType::uint16, "1 while the node answers"},
    {DiagnosticField::last_good_age_ms, "diag.last_good_age", ValueType::uint32,
     "ms since the last good poll (0xffffffff: never)"},
    {DiagnosticField::consecutive_timeouts, "diag.consecutive_timeouts", ValueType::uint16,
     "exchanges in a row without an answer: timeouts, and 'not reachable' replies of a "
     "forwarding device (Copley e 32); the node goes offline at offline_after"},
    {DiagnosticField::transactions, "diag.transactions", ValueType::uint32,
     "transactions with this node"},
    {DiagnosticField::timeouts, "diag.timeouts", ValueType::uint32, "transactions that timed out"},
    {DiagnosticField::errors, "diag.errors", ValueType::uint32,
     "device error replies and garbled replies"},
    {DiagnosticField::last_device_error, "diag.last_device_error", ValueType::uint16,
     "last error code the device replied (0xffff: wider than 16 bits, see "
     "diag.last_device_error_code)"},
    {DiagnosticField::action_status, "diag.action_status", ValueType::uint16,
     "0 idle, 1 busy, 2 done, 3 error"},
    {DiagnosticField::action_code, "diag.action_code", ValueType::uint16, "last action started"},
    {DiagnosticField::action_error, "diag.action_error", ValueType::uint16,
     "device error code of the last failed action (0xffff: not completed in time, 0xfffe: ended "
     "by failed condition, 0xfffd: unreachable, 0xfffc: no reply to a step, 0xfffb: garbled "
     "reply to a step, 0xfffa: the controller reset while the action ran)"},
    {DiagnosticField::node_state, "diag.node_state", ValueType::uint16,
     "0 starting, 1 online, 2 offline, 3 faulted (answers, refuses every poll)"},
    {DiagnosticField::unknown_writes, "diag.unknown_writes", ValueType::uint32,
     "commands sent without a valid reply: outcome unknown, answered 0x0B, not retried"},
    {DiagnosticField::data_age_ms, "diag.data_age", ValueType::uint32,
     "ms since the oldest polled value was read (0xffffffff: one never was)"},
    {DiagnosticField::unreachable, "diag.unreachable", ValueType::uint32,
     "transactions a forwarding device answered 'node unreachable' (Copley e 32); not in "
     "timeouts"},
    {DiagnosticField::last_device_error_code, "diag.last_device_error_code", ValueType::uint32,
     "last error code the device replied, all 32 bits (a CANopen SDO abort code)"},
};

RegisterEntry make_entry(RegisterEntry::Kind kind, uint16_t address, ValueType type,
                         std::string name, bool writable, std::string description) {
  RegisterEntry e;
  e.kind = kind;
  e.address = address;
  e.type = type;
  e.count = static_cast<uint16_t>(register_count(type));
  e.writable = writable;
  e.name = std::move(name);
  e.description = std::move(description);
  return e;
}

}  // namespace

RegisterMap RegisterMap::build(const std::vector<NodeBinding>& nodes, WordOrder order,
                               Diagnostics& diagnostics) {
  RegisterMap map;
  map.word_order_ = order;
  for (const auto& node : nodes) {
    UnitMap unit;
    unit.unit_id = node.unit_id;
    unit.node_index = node.node_index;
    unit.node_name = node.node_name;
    unit.bus_name = node.bus_name;
    unit.model = node.model;
    const Model& model = *node.model;
    auto& coils = unit.tables[static_cast<int>(Table::coils)];
    auto& inputs = unit.tables[static_cast<int>(Table::discrete_inputs)];
    auto& input_regs = unit.tables[static_cast<int>(Table::input_registers)];
    auto& holding = unit.tables[static_cast<int>(Table::holding_registers)];
    (void)coils;

    uint32_t next_input = 0;
    uint32_t next_holding = 0;
    uint32_t next_bit = 0;
    for (size_t i = 0; i < model.points.size(); ++i) {
      const auto& p = model.points[i];
      RegisterEntry e =
          make_entry(RegisterEntry::Kind::point, 0, p.type, p.name, p.writable(), p.description);
      e.index = static_cast<int>(i);
      e.units = p.units;
      e.scale = p.scale;
      if (p.writable()) {
        e.address = static_cast<uint16_t>(next_holding);
        next_holding += e.count;
        holding.push_back(e);
      } else {
        e.address = static_cast<uint16_t>(next_input);
        next_input += e.count;
        input_regs.push_back(e);
      }
      if (p.readable()) {
        for (const auto& b : p.bits) {
          RegisterEntry bit =
              make_entry(RegisterEntry::Kind::point_bit, static_cast<uint16_t>(next_bit++),
                         ValueType::boolean, p.name + "." + b.name, false, {});
          bit.index = static_cast<int>(i);
          bit.bit = b.bit;
          inputs.push_back(bit);
        }
      }
    }
    if (next_holding > layout::action_block)
      diagnostics.error(model.mark, fmt::format("model {}: writable points need {} holding "
                                                "registers, more than the {} before the action "
                                                "block",
                                                model.name, next_holding, layout::action_block));
    if (next_input > layout::diagnostics)
      diagnostics.error(model.mark, fmt::format("model {}: read-only points need {} input "
                                                "registers, more than the {} before the "
                                                "diagnostic block",
                                                model.name, next_input, layout::diagnostics));
    if (next_bit > layout::online_bit)
      diagnostics.error(model.mark,
                        fmt::format("model {}: too many status bits ({})", model.name, next_bit));

    if (!model.actions.empty()) {
      uint16_t a = layout::action_block;
      holding.push_back(make_entry(RegisterEntry::Kind::action_command, a++, ValueType::uint16,
                                   "action.command", true,
                                   "write an action code to run it; reads the last code"));
      holding.push_back(make_entry(RegisterEntry::Kind::action_status, a++, ValueType::uint16,
                                   "action.status", false, "0 idle, 1 busy, 2 done, 3 error"));
      holding.push_back(make_entry(RegisterEntry::Kind::action_error, a++, ValueType::uint16,
                                   "action.error", false,
                                   "device error code of the last failed action"));
      holding.push_back(make_entry(RegisterEntry::Kind::action_sequence, a++, ValueType::uint16,
                                   "action.sequence", false,
                                   "incremented each time an action is accepted"));
    }
    uint32_t next_setpoint = layout::setpoints;
    for (size_t i = 0; i < model.setpoints.size(); ++i) {
      const auto& s = model.setpoints[i];
      RegisterEntry e =
          make_entry(RegisterEntry::Kind::setpoint, static_cast<uint16_t>(next_setpoint), s.type,
                     s.name, true, s.description);
      e.index = static_cast<int>(i);
      e.units = s.units;
      e.scale = s.scale;
      next_setpoint += e.count;
      holding.push_back(e);
    }
    if (next_setpoint > layout::diagnostics)
      diagnostics.error(model.mark, fmt::format("model {}: setpoints overflow the holding "
                                                "registers reserved for them",
                                                model.name));

    uint32_t d = layout::diagnostics;
    for (const auto& diag : kDiagnostics) {
      RegisterEntry e = make_entry(RegisterEntry::Kind::diagnostic, static_cast<uint16_t>(d),
                                   diag.type, diag.name, false, diag.description);
      e.index = static_cast<int>(diag.field);
      d += e.count;
      input_regs.push_back(e);
    }
    RegisterEntry online =
        make_entry(RegisterEntry::Kind::diagnostic, layout::online_bit, ValueType::boolean,
                   "diag.online", false, "1 while the node answers");
    online.index = static_cast<int>(DiagnosticField::online);
    inputs.push_back(online);

    for (auto& table : unit.tables)
      std::sort(table.begin(), table.end(), [](const RegisterEntry& a, const RegisterEntry& b) {
        return a.address < b.address;
      });
    map.units_.emplace(unit.unit_id, std::move(unit));
  }
  return map;
}

const UnitMap* RegisterMap::unit(uint8_t unit_id) const {
  const auto it = units_.find(unit_id);
  return it == units_.end() ? nullptr : &it->second;
}

}  // namespace fieldgate
