#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sim/common/motion_axis.hpp"
#include "sim/common/wire_pacing.hpp"

// One Techno/isel C-series controller as shared/protocols/techno-cseries.md describes it: the
// `@<n>` grammar, one handshake character per line (capital moves answer at their end, lower-case
// ones at their start), positions as 24-bit hex, STOP (0xFF) and RESET (0xFE) bytes, program memory
// and homing that never ends without mechanics. Time only moves when the caller passes it in.
namespace fieldgate::sim::techno {

enum class Variant { it116g, c10, c116, c142 };
std::optional<Variant> parse_variant(std::string_view text);

struct ControllerOptions {
  Variant variant = Variant::c142;
  int device = 0;                // the GN of `@<GN>`
  int axes = 0;                  // axes defined at start; 0 = power-up state (everything answers 4)
  double acceleration = 75'000;  // steps/s², the card's jumper
  double home_distance = 5'000;  // steps between each axis and its home switch at start
  double travel = 100'000;       // machine range from the home switch; moves beyond answer 2
  bool mechanics = true;         // false: homing never finds the switch and never answers
  bool queries_during_motion = true;  // answer P/b/c while a lower-case motion runs
  bool position_ack = false;          // `0` before the 18 hex digits of P
  bool reply_cr = true;               // CR after the data of P/b/c
  bool stop_acknowledges = false;     // a capital command stopped by 0xFF still answers `0`
};

struct Counters {
  std::uint64_t lines = 0;     // complete lines for this device
  std::uint64_t queries = 0;   // P, b, c
  std::uint64_t commands = 0;  // every other line
  std::uint64_t stops = 0;
  std::uint64_t resets = 0;
  std::uint64_t other_device = 0;  // lines for another GN, ignored
  std::string last_command;
};

class Controller {
 public:
  // Bytes the controller sends and the instant they are ready (before turnaround and wire time).
  using Emit = std::function<void(SimTime at, std::string bytes)>;

  Controller(ControllerOptions options, SimTime now);
  void set_emit(Emit emit) { emit_ = std::move(emit); }

  // One line without its CR (an LF after the CR is dropped by the caller), at `now`.
  void line(std::string_view text, SimTime now);
  void stop_byte(SimTime now);
  void reset_byte(SimTime now);
  // Runs motions up to `now`: legs end, capital commands answer, buffered lines run.
  void advance(SimTime now);
  std::optional<SimTime> next_event() const;

  // Control channel verbs: mechanics on|off, estop on|off, inputs MASK, power-cycle, counters,
  // state. nullopt for other verbs.
  std::optional<std::string> control(std::string_view verb, std::span<const std::string> arguments,
                                     SimTime now);
  static std::string control_help();

  enum class Busy { idle, capital, lower_case, stopping };
  Busy busy() const { return busy_; }
  int axes() const { return axes_; }
  std::int64_t position(int axis, SimTime now) const;  // as P reports it
  const Counters& counters() const { return counters_; }
  bool program_mode() const { return program_mode_; }
  std::array<int, 2> outputs() const { return outputs_; }

 private:
  // One stage of a motion: legs run one after another, each from rest.
  struct Leg {
    enum class Kind { move, home, delay, zero };
    Kind kind = Kind::move;
    std::array<std::optional<double>, 3> value;  // per axis: distance, or position from origin
    std::array<double, 3> speed{};
    bool relative = true;
    int axis = 0;        // home, zero
    double seconds = 0;  // delay
  };
  struct Job {
    std::deque<Leg> legs;
    bool capital = false;
    bool endless_home = false;  // the current leg is a homing run that never ends
    std::optional<int> homing_axis;
    SimTime leg_end{};
    bool limit_hit = false;  // the current leg runs into the limit switch
  };

  void execute(std::string_view text, SimTime now);
  void execute_program_line(std::string_view text, SimTime now);
  void reply(SimTime at, char code);
  void reply_data(SimTime at, std::string data);
  std::optional<char> plan_move(std::string_view values, bool relative, std::deque<Leg>& legs,
                                SimTime now) const;
  std::optional<char> plan_home(int64_t mask, std::deque<Leg>& legs) const;
  std::optional<char> plan_arc(const std::vector<std::int64_t>& v, std::deque<Leg>& legs,
                               SimTime now) const;
  std::optional<char> plan_program(std::deque<Leg>& legs, SimTime now) const;
  void start_job(std::deque<Leg> legs, bool capital, SimTime now);
  void start_leg(SimTime now);
  void finish_leg(SimTime at);
  void finish_job(SimTime at);
  void run_buffered(SimTime at);
  double machine(int axis, SimTime now) const {
    return axes_motion_[static_cast<std::size_t>(axis)].position(now);
  }
  bool defined(int axis) const { return (axes_ >> axis) & 1; }

  ControllerOptions options_;
  Emit emit_;
  int axes_ = 0;
  std::array<MotionAxis, 3> axes_motion_;  // machine coordinates: 0 at the home switch
  std::array<double, 3> origin_{};         // machine coordinate where P reports 0
  std::array<double, 3> home_speed_{2000, 2000, 2000};
  int plane_ = 0;
  bool interpolation_3d_ = false;
  int circle_direction_ = 0;  // -1 CCW, 0 CW
  std::array<int, 2> outputs_{};
  int inputs_ = 0xff;  // open inputs read 1
  bool estop_ = false;
  std::optional<double> limit_x_;  // a limit switch on X at this position (control `limit`)
  Busy busy_ = Busy::idle;
  std::optional<Job> job_;
  bool stopped_capital_ = false;  // the ramp being run ended a capital command
  int stop_presses_ = 0;
  std::deque<std::string> buffered_;
  bool program_mode_ = false;
  std::vector<std::string> program_;
  Counters counters_;
};

// The 18 hex characters of `@0P` for X Y Z (24-bit two's complement, upper case).
std::string encode_positions(const std::array<std::int64_t, 3>& steps);

}  // namespace fieldgate::sim::techno
