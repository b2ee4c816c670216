#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

// Techno/isel C-series (IT116G, C10, C116, C142) serial grammar,
// shared/protocols/techno-cseries.md:
// `@<n><letter><values>\r` out, one handshake character back (`0` or an error character), with
// data after it for the queries. Pure functions, no I/O.
namespace fieldgate::techno {

inline constexpr char kAck = '0';
inline constexpr char kStopByte = '\xff';   // stop: decelerate, then pause (manual p.73)
inline constexpr char kResetByte = '\xfe';  // reset: halt at once, no ramp (p.68)
// How a model names the two raw bytes, which have no `@<n>` prefix and no CR.
inline constexpr std::string_view kStopCommand = "<stop>";
inline constexpr std::string_view kResetCommand = "<reset>";

inline constexpr int64_t kMaxSteps = 8'000'000;  // distance and position range (p.32, p.46)
inline constexpr int64_t kMinSpeed = 30;         // steps/s; the D error text says 20 on some pages
inline constexpr int64_t kMaxSpeed = 10'000;
inline constexpr int kPositionDigits = 18;  // `@0P`: 3 x 6 hex digits, X Y Z

enum class CommandKind {
  specify_axes,      // `7`: initialise, clears program memory
  move_relative,     // A / a
  move_absolute,     // M / m
  home,              // R / r
  zero,              // n
  home_speed,        // d
  position,          // P
  peek,              // b (RAM) / c (EPROM)
  poke,              // B
  plane,             // e
  interpolation_3d,  // z (C142)
  circle_direction,  // f (C142)
  circle,            // Y (C142)
  start_program,     // S / s
  clear_program,     // k
  enter_program,     // i: program download, not served through the gateway
  save_to_card,      // u
  trace,             // t
  stop,              // raw 0xFF
  reset,             // raw 0xFE
  unknown,
};

// When the controller answers (p.29): capital letters at the end of the motion or program,
// lower-case ones at its start; everything else at once.
enum class Handshake { immediate, at_start, at_end };

struct Command {
  CommandKind kind = CommandKind::unknown;
  Handshake handshake = Handshake::immediate;
  char letter = 0;
  std::string_view values;  // the text after the letter ("1000,500"); for specify_axes the digit
};

// Classifies the command a model writes, without the `@<n>` prefix.
Command classify(std::string_view command);
bool is_motion(CommandKind kind);  // moves, homing, circle, program start: they move axes

// "@<device><command>\r"; raw commands are their byte (stop `count` times).
std::string encode_command(int device, std::string_view command, int stop_count = 2);

// Comma-separated integers (tolerant of spaces around them, as the manual's examples have);
// nullopt on anything else. An empty text is an empty list.
std::optional<std::vector<int64_t>> parse_values(std::string_view text);

// Number of values a move carries for an axes definition (1 -> 2, 3 -> 4, 5 -> 6, 7 -> 8).
int move_value_count(int axes);
bool valid_axes_definition(int axes);  // 1, 3, 5, 7
int axis_count(int axes);              // bits set
// A home/zero mask is valid when it names at least one axis and only defined ones.
bool valid_axis_mask(int64_t mask, int axes);

// ---- handshake and replies ----

bool is_error_code(char c);
// The manual's meaning of a handshake character (p.90 and the command pages).
std::string_view error_text(char c);
// "'7' (55): illegal parameters ..." for logs and Reply::text.
std::string describe_error(char c);

// Frame splitters (see Link): the first complete reply at the start of buf, or 0.
std::size_t handshake_frame(std::string_view buf);
enum class PositionReply { automatic, bare, ack };  // model option position_reply
std::size_t position_frame(std::string_view buf, PositionReply mode);
std::size_t peek_frame(std::string_view buf);

// 24-bit two's complement (p.43, p.95 corrected): 7FFFFF -> 8388607, 800000 -> -8388608.
int64_t sign_extend_24(uint32_t raw);

struct ParsedReply {
  enum class Kind { ok, error, malformed };
  Kind kind = Kind::malformed;
  char code = 0;                // the handshake character
  std::vector<int64_t> values;  // for queries
  std::string problem;          // for malformed
};

ParsedReply parse_handshake(std::string_view frame);
// `@0P`: optional leading `0` handshake, 18 hex digits ("eighteen characters", p.43), optional
// CR/LF. A controller with fewer axes (`fitted_axes` 1 or 2, the model's) may also answer 6 or
// 12 digits, padded with 0 so field numbers stay X=0, Y=1, Z=2. Fewer digits than that are a
// reply cut short (an idle gap inside it), never an axis at 0.
ParsedReply parse_positions(std::string_view frame, int fitted_axes = 3);
// `@0b`/`@0c`: `0` then two hex digits.
ParsedReply parse_peek(std::string_view frame);

// ---- motion timing (digest §1.4) ----

// One leg of `distance` steps at `speed` steps/s with `acceleration` steps/s² ramps: d/v + v/a
// when the axis reaches its speed, else 2 sqrt(d/a).
double leg_seconds(double distance, double speed, double acceleration);

struct MotionContext {
  int axes = 7;                                    // defined axes
  int plane = 0;                                   // e: 0 XY, 1 XZ, 2 YZ
  double acceleration = 75'000;                    // steps/s²
  std::array<std::optional<int64_t>, 3> position;  // last known X Y Z
  std::array<double, 3> home_speed{2000, 2000, 2000};
  std::array<double, 3> travel{50'000, 50'000, 50'000};  // steps an axis can be away from home
};

// Which axis (0 X, 1 Y, 2 Z) each value pair of a move drives: the plane pair together, then the
// third axis twice (Z1, Z2). Axes 5 is taken as X, Z1, Z2 [inf].
std::vector<int> pair_axes(int axes, int plane);

struct MotionEstimate {
  double seconds = 0;                                  // legs in sequence, no margin
  std::array<std::optional<int64_t>, 3> end_position;  // where the axes end, where known
};

// Time a motion command takes; nullopt if it does not move or its values do not fit the axes.
std::optional<MotionEstimate> estimate_motion(const Command& command,
                                              const std::vector<int64_t>& values,
                                              const MotionContext& context);

// Parses a node address: the device number, one character 0-9 (`@07` is device 0, axes 7).
std::optional<int> parse_device(std::string_view text, std::string& error);

}  // namespace fieldgate::techno
