#include "mapping/axis_profile.hpp"

namespace fieldgate {

namespace {
constexpr std::array<std::string_view, kProfileCommandCount> kCommandNames = {
    "none",         "power_on",     "power_off", "home", "move_absolute", "move_relative",
    "jog_positive", "jog_negative", "stop",      "halt", "reset"};
}  // namespace

std::string_view to_string(StatusBit bit) {
  switch (bit) {
    case StatusBit::enabled:
      return "enabled";
    case StatusBit::homed:
      return "homed";
    case StatusBit::moving:
      return "moving";
    case StatusBit::in_position:
      return "in_position";
    case StatusBit::error:
      return "error";
    case StatusBit::limit_positive:
      return "limit_positive";
    case StatusBit::limit_negative:
      return "limit_negative";
    case StatusBit::warning:
      return "warning";
    case StatusBit::velocity_reported:
      return "velocity_reported";
    case StatusBit::online:
      return "online";
  }
  return "?";
}

std::string_view to_string(PlcopenState state) {
  switch (state) {
    case PlcopenState::disabled:
      return "Disabled";
    case PlcopenState::standstill:
      return "Standstill";
    case PlcopenState::homing:
      return "Homing";
    case PlcopenState::discrete_motion:
      return "DiscreteMotion";
    case PlcopenState::continuous_motion:
      return "ContinuousMotion";
    case PlcopenState::stopping:
      return "Stopping";
    case PlcopenState::error_stop:
      return "ErrorStop";
  }
  return "?";
}

std::string_view to_string(ProfileCommand command) {
  const auto i = static_cast<std::size_t>(command);
  return i < kCommandNames.size() ? kCommandNames[i] : "?";
}

std::optional<ProfileCommand> profile_command_named(std::string_view name) {
  for (std::size_t i = 1; i < kCommandNames.size(); ++i)
    if (kCommandNames[i] == name) return static_cast<ProfileCommand>(i);
  return std::nullopt;
}

std::string_view to_string(CommandStatus status) {
  switch (status) {
    case CommandStatus::idle:
      return "idle";
    case CommandStatus::busy:
      return "busy";
    case CommandStatus::done:
      return "done";
    case CommandStatus::error:
      return "error";
    case CommandStatus::aborted:
      return "aborted";
  }
  return "?";
}

std::string_view to_string(ProfileSetpoint setpoint) {
  switch (setpoint) {
    case ProfileSetpoint::target:
      return "target";
    case ProfileSetpoint::distance:
      return "distance";
    case ProfileSetpoint::velocity:
      return "velocity";
    case ProfileSetpoint::jog_velocity:
      return "jog_velocity";
    case ProfileSetpoint::acceleration:
      return "acceleration";
    case ProfileSetpoint::deceleration:
      return "deceleration";
    case ProfileSetpoint::home_velocity:
      return "home_velocity";
  }
  return "?";
}

uint16_t ProfileAxisDef::supported_mask() const {
  uint16_t mask = 0;
  for (const auto& [command, _] : commands)
    mask |= static_cast<uint16_t>(1u << static_cast<unsigned>(command));
  return mask;
}

PlcopenState derive_state(const AxisObservation& o) {
  if (o.error || o.error_latched) return PlcopenState::error_stop;
  if (!o.enabled) return PlcopenState::disabled;
  const bool busy = o.status == CommandStatus::busy;
  switch (o.command) {
    case ProfileCommand::stop:
      // PLCopen: Stopping until the stop is done; 'done' means the axis stands still.
      if (busy) return PlcopenState::stopping;
      break;
    case ProfileCommand::home:
      if (busy) return PlcopenState::homing;
      break;
    case ProfileCommand::move_absolute:
    case ProfileCommand::move_relative:
    case ProfileCommand::halt:
      if (busy) return PlcopenState::discrete_motion;
      break;
    case ProfileCommand::jog_positive:
    case ProfileCommand::jog_negative:
      // A velocity command is done once the drive took it; its motion goes on.
      if (busy || (o.moving && o.status == CommandStatus::done))
        return PlcopenState::continuous_motion;
      break;
    default:
      break;
  }
  // Motion nobody commanded through the profile (the native unit, a homing the controller runs
  // by itself): a discrete motion as far as the profile can tell.
  if (o.moving) return PlcopenState::discrete_motion;
  return PlcopenState::standstill;
}

std::optional<uint16_t> refusal(PlcopenState state, ProfileCommand command) {
  const bool motion = command == ProfileCommand::home || command == ProfileCommand::move_absolute ||
                      command == ProfileCommand::move_relative ||
                      command == ProfileCommand::jog_positive ||
                      command == ProfileCommand::jog_negative;
  switch (state) {
    case PlcopenState::error_stop:
      if (command == ProfileCommand::reset || command == ProfileCommand::power_off)
        return std::nullopt;
      return kProfileErrorErrorStop;
    case PlcopenState::disabled:
      if (motion || command == ProfileCommand::halt) return kProfileErrorDisabled;
      return std::nullopt;
    case PlcopenState::stopping:
      if (motion || command == ProfileCommand::halt) return kProfileErrorStopping;
      return std::nullopt;
    default:
      return std::nullopt;
  }
}

}  // namespace fieldgate
