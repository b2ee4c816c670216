#pragma once

#include <array>
#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "drivers/techno_c/techno_codec.hpp"
#include "mapping/diagnostics.hpp"
#include "mapping/model.hpp"
#include "mapping/model_options.hpp"

// What a techno-c model's `options:` say, and the load-time checks that keep every Modbus write
// from reaching the controller with a value count or range it would refuse.
namespace fieldgate::techno {

// Fields of the `P` read (`read: {request: P, field: N, format: hex24}`). 0..2 come from the
// controller; the family adds the others.
inline constexpr int kFieldX = 0;
inline constexpr int kFieldInMotion = 3;  // 1 while a lower-case motion may still be running
inline constexpr int kFieldUnitsX = 4;    // 4..6: X Y Z in user units (needs steps_per_unit)
// The code of an error the controller reported after acknowledging a lower-case motion (ASCII of
// the character, e.g. 50 for `2`), or kShortOfTarget; 0 while none. Cleared by the next motion.
inline constexpr int kFieldMotionFault = 7;  // 1 while kFieldMotionError is not 0
inline constexpr int kFieldMotionError = 8;
inline constexpr int kPositionFields = 9;
// The axes came to rest away from the position the move commanded, with no error character.
inline constexpr int64_t kShortOfTarget = 1;

struct Profile {
  std::string model;
  // The controller, as the model names it, and what sets it apart: a new variant is a model file
  // that gives these (README "Variants").
  std::string variant = "c142";
  int fitted_axes = 3;           // X, XY or XYZ: the axes the controller has
  bool arc_commands = true;      // 3D interpolation and circles (z, f, Y: the C142's card 5.0)
  int axes = 7;                  // the axes definition the controller is initialised with
  double acceleration = 75'000;  // steps/s², from the card's jumper (Hz/ms x 1000)
  double home_speed = 2000;      // the controller's default until `d` is sent (p.63)
  std::array<double, 3> travel{50'000, 50'000, 50'000};  // furthest an axis can be from home
  double timeout_factor = 1.25;
  std::chrono::microseconds timeout_margin{std::chrono::seconds(1)};
  std::chrono::microseconds program_timeout{std::chrono::seconds(60)};
  std::chrono::microseconds stop_settle{std::chrono::milliseconds(500)};
  std::optional<std::array<double, 3>> steps_per_unit;
  double unit_resolution = 0.001;  // user units per register count
  PositionReply position_reply = PositionReply::automatic;
  int stop_bytes = 2;
  bool stop_on_timeout = true;
  bool init_on_connect = false;
  // A `4` (axes not defined: the controller powered up) is answered by sending the axes
  // definition and the request again; a motion only on first contact (see README).
  bool init_when_undefined = true;
  // A lower-case motion is over once the polled positions stood still this long.
  std::chrono::microseconds motion_settle{std::chrono::milliseconds(300)};

  bool operator==(const Profile&) const = default;
};

// The options a techno-c model may set, and a model's options read through them; errors carry
// the option's mark.
const ModelOptionSpecs& option_specs();
Profile read_profile(const Model& model, Diagnostics& diagnostics);

// Checks every read, write and action step of a model against the grammar and the profile:
// value counts for the defined axes, speed/distance/mask ranges of literals and of the
// setpoints or point limits behind placeholders, arc commands, raw bytes.
void check_model(const Model& model, const Profile& profile, Diagnostics& diagnostics);

// What reaches every controller on a line at once (the stop and reset bytes, the ramp after
// them) follows the line's models merged: the slowest of them, units only if they agree.
Profile merge_profiles(const std::vector<Profile>& profiles);

}  // namespace fieldgate::techno
