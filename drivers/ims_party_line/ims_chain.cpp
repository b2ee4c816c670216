#include "drivers/ims_party_line/ims_chain.hpp"

#include <fmt/format.h>

#include <cmath>

#include "drivers/ims_party_line/ims_codec.hpp"

namespace fieldgate::ims {

namespace {

std::optional<double> field(std::string_view command, std::size_t index) {
  if (command.empty()) return std::nullopt;
  const auto data = parse_data(normalize_command(command).substr(1));
  if (!data || data->fields.size() <= index) return std::nullopt;
  return data->fields[index];
}

}  // namespace

std::optional<RefusalReply> ChainShadow::check(char name, std::string_view command,
                                               Clock::time_point now) const {
  // ESC or ^C inside an addressed line would stop or reset every unit on the chain.
  if (command.empty() || command.find_first_of("\r\n\x1b\x03") != std::string_view::npos)
    return RefusalReply{Refusal::invalid_line,
                        fmt::format("'{}' is no addressed party-line command (empty, or CR, LF, "
                                    "ESC or ^C inside)",
                                    printable(command))};
  const auto it = units_.find(name);
  const Unit* unit = it == units_.end() ? nullptr : &it->second;
  const CommandClass kind = classify(command);
  if (kind == CommandClass::parameter && command.front() == 'A') {
    const double v = field(command, 0).value_or(0);
    if (v < 0 || v > 56 || std::fmod(v, 8.0) != 0.0)
      return RefusalReply{Refusal::output_value,
                          fmt::format("A{}: outputs are written as 8*OUT1 + 16*OUT2 + 32*OUT3 "
                                      "(0, 8, ..., 56); other values disturb the input ports",
                                      v)};
  }
  if ((kind == CommandClass::index || kind == CommandClass::origin) && unit && unit->moving &&
      unit->status_seen) {
    if (kind == CommandClass::origin)
      return RefusalReply{Refusal::axis_moving,
                          fmt::format("unit {}: set origin is refused while the axis moves", name)};
    return RefusalReply{Refusal::axis_moving,
                        fmt::format("unit {}: the axis is moving; '{}' would queue behind the "
                                    "running motion and the unit would answer nothing until it "
                                    "starts",
                                    name, command)};
  }
  if (command.front() == 'S' && unit && unit->last_save &&
      now - *unit->last_save < limits(name).save_interval) {
    const auto ago = std::chrono::duration_cast<std::chrono::seconds>(now - *unit->last_save);
    return RefusalReply{
        Refusal::eeprom_rate,
        fmt::format("unit {}: parameters were saved to EEPROM {} s ago; saves are limited to one "
                    "per {} s to spare the EEPROM's write cycles (option save_interval)",
                    name, ago.count(),
                    std::chrono::duration<double>(limits(name).save_interval).count())};
  }
  return std::nullopt;
}

void ChainShadow::motion_started(Unit& unit, std::string_view command) {
  unit.moving = true;
  unit.jogging = false;
  switch (command.front()) {
    case 'F':
      unit.step_rate = std::abs(field(command, 0).value_or(0));
      break;
    case '+':
    case '-':
    case 'R':
    case 'G':
      unit.step_rate = unit.slew.value_or(0);
      break;
    default:
      break;
  }
}

void ChainShadow::acknowledged(char name, std::string_view command, Clock::time_point now,
                               std::optional<int64_t> result) {
  if (command.empty()) return;
  Unit& unit = units_[name];
  switch (classify(command)) {
    case CommandClass::parameter:
      if (command.front() == 'V') unit.slew = field(command, 0);
      if (command.front() == 'C') unit.slew.reset();  // C0 reloads the saved parameters
      break;
    case CommandClass::index:
      motion_started(unit, command);
      break;
    case CommandClass::velocity:
      if (const double v = field(command, 0).value_or(0); v != 0) {
        unit.moving = true;
        unit.jogging = true;
        unit.step_rate = std::abs(v);
      }
      // M0 ramps down from the current speed: still fast until `^` says idle.
      break;
    case CommandClass::query:
      if (command.front() == '^' && result) {
        unit.status_seen = true;
        if ((*result & status::meaningful) == 0) {
          unit.moving = false;
          unit.jogging = false;
          unit.step_rate = 0;
        } else {
          unit.moving = true;  // e.g. started by the jog inputs or a program
        }
      }
      break;
    case CommandClass::eeprom:
      if (command.front() == 'S') unit.last_save = now;
      break;
    default:
      break;
  }
}

void ChainShadow::global(std::string_view command, Clock::time_point now) {
  if (command.empty()) return;
  switch (command.front()) {
    case kEscape:
      for (auto& [name, unit] : units_) {
        unit.moving = false;
        unit.jogging = false;
        unit.step_rate = 0;
      }
      return;
    case kControlC:
      // Every unit reloads its saved parameters and forgets the motion (§1 "Reset").
      for (auto& [name, unit] : units_) {
        unit.moving = false;
        unit.jogging = false;
        unit.step_rate = 0;
        unit.slew.reset();
      }
      return;
    case kSoftStop:
      return;  // decelerates; `^` tells when each axis is idle
    default:
      for (auto& [name, unit] : units_) acknowledged(name, command, now);
  }
}

const ChainShadow::Limits& ChainShadow::limits(char name) const {
  static const Limits defaults;
  const auto it = limits_.find(name);
  return it == limits_.end() ? defaults : it->second;
}

bool ChainShadow::fast() const {
  for (const auto& [name, unit] : units_)
    if (unit.step_rate > limits(name).fast_step_rate) return true;
  return false;
}

double ChainShadow::step_rate(char name) const {
  const auto it = units_.find(name);
  return it == units_.end() ? 0.0 : it->second.step_rate;
}

bool ChainShadow::moving(char name) const {
  const auto it = units_.find(name);
  return it != units_.end() && it->second.moving;
}

bool ChainShadow::jogging(char name) const {
  const auto it = units_.find(name);
  return it != units_.end() && it->second.moving && it->second.jogging;
}

}  // namespace fieldgate::ims
