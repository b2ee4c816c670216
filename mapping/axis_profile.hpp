#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mapping/diagnostics.hpp"

namespace fieldgate {

// The PLCopen-style axis profile: one fixed Modbus page that every axis presents on its own unit
// ID, whatever its controller family. docs/axis-profile.md is generated from this page
// (`fieldgate map --profile`).
namespace axis_profile {

// Input registers (0-based).
inline constexpr uint16_t actual_position = 0;  // int32, 2 registers
inline constexpr uint16_t actual_velocity = 2;  // int32, 2 registers; 0 where not reported
inline constexpr uint16_t status_word = 4;
inline constexpr uint16_t plcopen_state = 5;
inline constexpr uint16_t error_id = 6;  // the device's code of the axis error
inline constexpr uint16_t sequence_echo = 7;
inline constexpr uint16_t command_status = 8;
inline constexpr uint16_t command_echo = 9;
inline constexpr uint16_t command_error = 10;
inline constexpr uint16_t supported_commands = 11;  // bit n: command code n is supported
inline constexpr uint16_t input_count = 12;

// Holding registers (0-based).
inline constexpr uint16_t target_position = 0;  // int32: target (absolute), distance (relative)
inline constexpr uint16_t velocity = 2;         // int32
inline constexpr uint16_t acceleration = 4;     // int32
inline constexpr uint16_t deceleration = 6;     // int32
inline constexpr uint16_t command_code = 8;
inline constexpr uint16_t sequence_number = 9;  // written together with command_code
inline constexpr uint16_t holding_count = 10;

}  // namespace axis_profile

enum class StatusBit : int {
  enabled = 0,
  homed = 1,
  moving = 2,
  in_position = 3,  // at standstill and the last command done
  error = 4,
  limit_positive = 5,
  limit_negative = 6,
  warning = 7,
  velocity_reported = 8,  // actual velocity is the controller's own reading
  online = 9,             // the node answers its polls
};
inline constexpr int kStatusBitCount = 10;
std::string_view to_string(StatusBit bit);
std::optional<StatusBit> status_bit_named(std::string_view name);

enum class PlcopenState : uint16_t {
  disabled = 0,
  standstill = 1,
  homing = 2,
  discrete_motion = 3,
  continuous_motion = 4,
  stopping = 5,
  error_stop = 6,
};
std::string_view to_string(PlcopenState state);

enum class ProfileCommand : uint16_t {
  none = 0,
  power_on = 1,
  power_off = 2,
  home = 3,
  move_absolute = 4,
  move_relative = 5,
  jog_positive = 6,  // MC_MoveVelocity, positive direction
  jog_negative = 7,  // MC_MoveVelocity, negative direction
  stop = 8,          // MC_Stop
  halt = 9,          // MC_Halt
  reset = 10,        // MC_Reset
};
inline constexpr uint16_t kProfileCommandCount = 11;
std::string_view to_string(ProfileCommand command);
std::optional<ProfileCommand> profile_command_named(std::string_view name);

enum class CommandStatus : uint16_t { idle = 0, busy = 1, done = 2, error = 3, aborted = 4 };
std::string_view to_string(CommandStatus status);

// Command errors the gateway gives (device codes are below 0xff00).
inline constexpr uint16_t kProfileErrorDisabled = 0xfff0;     // motion while Disabled
inline constexpr uint16_t kProfileErrorErrorStop = 0xffef;    // only reset/power off in ErrorStop
inline constexpr uint16_t kProfileErrorStopping = 0xffee;     // motion while a stop runs
inline constexpr uint16_t kProfileErrorDeviceFault = 0xffed;  // error bit without a device code
// The controller reset, power-cycled, signed on or booted while the command (or a native action)
// ran: whatever it had done of it is lost, so it never ends done. An action code, shared with
// the native action block.
inline constexpr uint16_t kActionErrorControllerReset = 0xfffa;
// A move or home whose actions completed but whose axis stands still away from the command's
// target (or not homed): the controller did not run the command to its end (a reset, a limit).
inline constexpr uint16_t kProfileErrorNotAtTarget = 0xffec;

// Which setpoint of the model a profile value feeds.
enum class ProfileSetpoint {
  target,
  distance,
  velocity,
  jog_velocity,
  acceleration,
  deceleration,
  home_velocity,
};
inline constexpr int kProfileSetpointCount = 7;
std::string_view to_string(ProfileSetpoint setpoint);
std::optional<ProfileSetpoint> profile_setpoint_named(std::string_view name);

// A status bit taken from a polled point: bit `bit` (or the whole value) equals / differs from a
// value; `constant` instead gives a fixed answer (an axis that is always enabled).
struct StatusSource {
  std::string point;
  std::optional<int> bit;
  int64_t value = 1;
  bool negate = false;  // not_equals
  std::optional<bool> constant;
  SourceMark mark;
};

// How one axis of a model maps itself onto the profile (the model's axis_profile: section).
struct ProfileAxisDef {
  std::string name;  // "axis" for a single-axis model; x, y, z, ... otherwise
  std::string position;
  std::string velocity;    // empty: not reported
  std::string error_code;  // point holding the device's error code, optional
  std::map<StatusBit, StatusSource> status;
  // Profile value -> a setpoint of the model, or a writable point (written, confirmed, before the
  // command's first action).
  std::map<ProfileSetpoint, std::string> setpoints;
  // Model setpoints given before every command of this axis: fixed values (the axis number of a
  // multi-axis controller) and the latest value of a polled point (the other axes' positions, for
  // a controller whose absolute move names every axis).
  std::map<std::string, int64_t> fixed;
  std::map<std::string, std::string> hold;
  // Per command: the model's actions run in order, each awaited to done. Absent: unsupported.
  std::map<ProfileCommand, std::vector<std::string>> commands;
  // The reset action acts only on a faulted axis: outside ErrorStop, MC_Reset sends nothing and
  // is done (a CiA 402 fault reset writes the controlword and would switch an enabled drive off).
  bool reset_only_in_error_stop = false;
  // How far from its target a move may end and still be done, in the position's units.
  int64_t position_tolerance = 0;
  // A polled point whose value changes at every reset of the controller (a count of the unit's
  // sign-on messages): a command across such a change ends failed.
  std::string reset_count;
  SourceMark mark;

  bool supports(ProfileCommand c) const { return commands.count(c) != 0; }
  uint16_t supported_mask() const;
};

// What the PLCopen state is derived from.
struct AxisObservation {
  bool enabled = false;
  bool moving = false;
  bool error = false;          // the controller's error bit
  bool error_latched = false;  // a command failed at the device and no Reset has completed
  ProfileCommand command = ProfileCommand::none;  // the last command accepted
  CommandStatus status = CommandStatus::idle;
};

// The PLCopen axis state diagram over the observation: ErrorStop until a Reset completes and the
// controller reports no error; Disabled while not enabled; Stopping until a Stop is done; Homing
// while a home runs; ContinuousMotion while a jog's motion goes on; DiscreteMotion while a move
// (or a Halt) runs; otherwise Standstill.
PlcopenState derive_state(const AxisObservation& o);

// Whether a command may start in a state; nullopt if so, else the command error it gets.
std::optional<uint16_t> refusal(PlcopenState state, ProfileCommand command);

// The one-page description of the profile, Markdown.
std::string write_axis_profile_document();

}  // namespace fieldgate
