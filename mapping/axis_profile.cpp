#include "mapping/axis_profile.hpp"

namespace fieldgate {

namespace {
// Names by enum value (every enum of the page counts from 0 without gaps).
constexpr std::array<std::string_view, kStatusBitCount> kStatusBitNames = {
    "enabled",        "homed",          "moving",  "in_position",       "error",
    "limit_positive", "limit_negative", "warning", "velocity_reported", "online"};
constexpr std::array<std::string_view, 7> kStateNames = {
    "Disabled",         "Standstill", "Homing",   "DiscreteMotion",
    "ContinuousMotion", "Stopping",   "ErrorStop"};
constexpr std::array<std::string_view, kProfileCommandCount> kCommandNames = {
    "none",         "power_on",     "power_off", "home", "move_absolute", "move_relative",
    "jog_positive", "jog_negative", "stop",      "halt", "reset"};
constexpr std::array<std::string_view, 5> kCommandStatusNames = {"idle", "busy", "done", "error",
                                                                 "aborted"};
constexpr std::array<std::string_view, kProfileSetpointCount> kSetpointNames = {
    "target",       "distance",     "velocity",     "jog_velocity",
    "acceleration", "deceleration", "home_velocity"};

template <std::size_t N, typename Enum>
std::string_view name_in(const std::array<std::string_view, N>& names, Enum value) {
  const auto i = static_cast<std::size_t>(value);
  return i < N ? names[i] : "?";
}

template <typename Enum, std::size_t N>
std::optional<Enum> named_in(const std::array<std::string_view, N>& names, std::string_view name,
                             std::size_t first = 0) {
  for (std::size_t i = first; i < N; ++i)
    if (names[i] == name) return static_cast<Enum>(i);
  return std::nullopt;
}
}  // namespace

std::string_view to_string(StatusBit bit) {
  return name_in(kStatusBitNames, bit);
}
std::string_view to_string(PlcopenState state) {
  return name_in(kStateNames, state);
}
std::string_view to_string(ProfileCommand command) {
  return name_in(kCommandNames, command);
}
std::string_view to_string(CommandStatus status) {
  return name_in(kCommandStatusNames, status);
}
std::string_view to_string(ProfileSetpoint setpoint) {
  return name_in(kSetpointNames, setpoint);
}

std::optional<StatusBit> status_bit_named(std::string_view name) {
  return named_in<StatusBit>(kStatusBitNames, name);
}
// "none" (0) is no command anyone names.
std::optional<ProfileCommand> profile_command_named(std::string_view name) {
  return named_in<ProfileCommand>(kCommandNames, name, 1);
}
std::optional<ProfileSetpoint> profile_setpoint_named(std::string_view name) {
  return named_in<ProfileSetpoint>(kSetpointNames, name);
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
