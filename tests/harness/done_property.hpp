#pragma once

// Issue 49, "done means arrived": what every family's done property test
// (tests/families/*/*_done_property_test.cpp) shares. Against a family's simulator (or an
// independent unit), a seeded random run drives the axis profile units with three kinds of
// traffic besides plain moves:
//  - commands to every axis of a node at once (one connection per axis, released together);
//  - a controller reset or power cycle injected through the simulator's control channel while a
//    move runs;
//  - home and move on freshly started axes whose velocity register (holding 2-3) was never
//    written.
// Each command is watched until it ends. The property: every command that reads done
// (command_status 2) has the device's own position, asked of the simulator the moment done was
// read, at that command's target (a home: at the reference), and no reset was injected between
// the command and its done while the device was still short of the target. A command with the
// velocity never written ends (done, error, or refused with 0x03) within seconds. Not vacuous:
// some simultaneous commands, some resets that interrupted a move, some done.

#include <gtest/gtest.h>

#include <chrono>
#include <climits>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "harness.hpp"

namespace fieldgate::test {

// Profile commands and statuses (docs/axis-profile.md).
inline constexpr uint16_t kPowerOn = 1, kHome = 3, kMoveAbsolute = 4, kMoveRelative = 5,
                          kResetCommand = 10;
inline constexpr int kBusy = 1, kDone = 2, kError = 3, kAborted = 4;
inline constexpr uint16_t kControllerReset = 0xfffa, kNotAtTarget = 0xffec;

// One profile axis of the plant.
struct DoneAxis {
  int unit = 0;        // its profile unit ID
  int node = 0;        // the axes of one node take simultaneous commands together
  int controller = 0;  // what one injected reset power-cycles; -1: never reset
};

// What a family's done property test says of its plant.
struct DoneProperty {
  std::vector<DoneAxis> axes;
  // The device's own position of the axis behind a profile unit, in the profile's units, asked
  // of the simulator's control channel; nullopt when it did not answer.
  std::function<std::optional<int64_t>(int unit)> device_position;
  // Resets or power-cycles a controller (DoneAxis::controller) through the control channel.
  std::function<void(int controller)> reset;
  // Absolute targets are drawn in [min_target, max_target]. Every move travels at least
  // min_travel, and no target lies closer than that to 0, where a reset leaves an axis.
  int32_t min_target = -100000, max_target = 100000, min_travel = 1000;
  // A move that a reset is to interrupt travels at least this far (long enough to be mid-way).
  int32_t long_travel = 20000;
  // The longest distance the model takes for move_relative: a longer move goes absolute.
  int64_t max_distance = INT32_MAX;
  // Written to every axis after the fresh-axis phase (acceleration to holding 4-5 and 6-7); 0:
  // left alone.
  int32_t velocity = 0, acceleration = 0;
  int64_t tolerance = 0;                     // the model's position_tolerance
  std::optional<int64_t> home_position = 0;  // where a home that ends done leaves the device
  bool power_on = false;   // power_on every axis at the start and after a reset (Copley)
  bool fresh_move = true;  // the fresh-axis phase also moves with the velocity never written
  // A reset goes in between this long after the move was sent (drawn), once the device shows
  // the axis short of its target.
  std::chrono::milliseconds reset_after_min{60}, reset_after_max{400};
  // How long a command may run before it counts as hung (and the run stops).
  std::chrono::milliseconds command_timeout{20000};
  std::chrono::milliseconds fresh_timeout{20000};  // "within seconds", not the 10-minute timeout
  int rounds = 12;  // a third simultaneous, a third with a reset, a third single moves
  // The family sees a reset on the line (a sign-on, a boot-up, a power-up state): a move a reset
  // interrupted that ends failed carries 0xfffa. False where nothing on the line shows it (the
  // move then fails on the position proof, 0xffec).
  bool reset_visible = true;
};

// What a run saw.
struct DoneCounts {
  int commands = 0;      // commands the gateway took (sequence_echo showed them)
  int simultaneous = 0;  // commands sent together with the other axes of their node
  int resets = 0;        // resets injected
  int interrupted = 0;   // commands running, short of their target, when a reset went in
  int dones = 0, aborted = 0, hung = 0;
  std::map<int, int> failures;  // command_error -> count
  std::map<int, int> refused;   // Modbus exception of a command write the gateway did not take
  int fresh_commands = 0, fresh_ended = 0, fresh_refused = 0;
  int false_dones = 0;
  std::vector<std::string> false_done_cases;  // what was served vs the device, one per case
};

std::ostream& operator<<(std::ostream& os, const DoneCounts& counts);

// The seed of a run: FIELDGATE_DONE_SEED if set (to replay a case), else `fallback`.
unsigned done_seed(unsigned fallback);

// The run: the fresh-axis phase, then `rounds` seeded rounds; returns what it saw. Adds gtest
// failures for every false done, every hung command and a vacuous run.
DoneCounts run_done_property(Plant& plant, unsigned seed, const DoneProperty& property);
// The same against a daemon started otherwise (a CAN bus: tests/families/canopen), listening for
// Modbus TCP on the loopback `port`.
DoneCounts run_done_property(int port, ChildProcess& daemon, unsigned seed,
                             const DoneProperty& property);

// A simulator's answer to a control line: the log from the last `tag` on, its first line only.
std::optional<std::string> control_line(ChildProcess& sim, const std::string& line,
                                        const std::string& tag);

// One request line to a unit_common.Control socket (tests/independent) and its answer line.
std::optional<std::string> unix_socket_request(const std::string& path, const std::string& line);

// The integer after `key` (e.g. "x=") in a control answer; nullopt if absent. Accepts a
// fraction (rounded to the nearest integer).
std::optional<int64_t> field_after(const std::string& text, const std::string& key);

}  // namespace fieldgate::test
