#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sim/common/motion_axis.hpp"
#include "sim/common/wire_pacing.hpp"

namespace fieldgate::sim::centent {

// Behaviour choices where the manual is ambiguous (README "Interpretations").
struct UnitSettings {
  bool position_reply_xp = false;  // XP=…h (p.2) instead of X=…h (p.35)
  // An absolute target compared with the position as signed 32-bit numbers, so a move crosses 0
  // instead of running round the register ("positive only", §9 #20: either reading).
  bool signed_absolute = false;
  bool accept_backslash_overflow = true;  // M1\- / M1\+ (p.5 headings)
  bool accept_plain_overflow = true;      // M1- / M1+ (p.6 heading, §9 #11)
  std::size_t staging = 8;                // per-unit motion staging (≥ 8 per motor, p.7)
  std::size_t immediate_queue = 20;       // ≈ 20 instructions (p.5)
  double home_distance_steps = 2000;      // power-up position to the home switch
};

// One CN0170: two axes, I/O, modes and queues, executing instructions the chain hands it.
// Positions are kept in raw units (1/1024 full step) as the controller's registers are.
class Cn0170Unit {
 public:
  struct Axis {
    explicit Axis(char l) : letter(l) {}
    char letter;
    MotionAxis motion;
    HomingSequence homing;
    double base_velocity = 200;  // steps/s, .25 resolution
    double max_velocity = 2000;
    int acceleration = 156;  // register, × 64 steps/s² (XA=10000 -> 156)
    int profile = 17;        // 1..16, 17 L, 18 P, 19 U
    std::array<int, 16> user_profile{};
    bool position_trigger = false, velocity_trigger = false, home_cw = false, io_link = false;
    bool modulo_quit = false, handshake = false;
    int resolution = 10;
    int standby_delay = 0;
    int joystick = 0;
    double home_switch = 0;  // in axis coordinates (raw)
    SimTime busy_until{};    // queued motion for this axis waits until then
    bool endless = false;    // speed control or joystick: the next instruction takes over
    bool move_pending = false;
    std::optional<SimTime> vmax_at;
  };

  Cn0170Unit(int number, const UnitSettings& settings, SimTime now);

  int number() const { return number_; }
  void set_number(int n) { number_ = n; }

  // One instruction (no ';'), at `now`; reply lines (without unit prefix or terminator) are
  // appended to `replies`. Returns true for K, which the chain relays downstream.
  bool execute(std::string_view instruction, SimTime now, std::vector<std::string>& replies);
  // Runs the motion queues up to `now`; messages the unit sends on its own (XP, XV, Q*, *Q)
  // are appended to `events`.
  void advance(SimTime now, std::vector<std::string>& events);
  // K: motion stops dead, queues and staging are cleared, the program is rewound.
  void kill(SimTime now);
  // Power-up after a reset: motion, queues, clock, outputs and selection are lost; parameters,
  // the program, the mode and the unit number are battery-backed.
  void power_up(SimTime now);

  int mode() const { return mode_; }
  Axis& axis(char letter) { return letter == 'Y' ? y_ : x_; }
  const Axis& axis(char letter) const { return letter == 'Y' ? y_ : x_; }
  std::uint32_t position_register(char letter, SimTime now) const;
  bool moving(char letter, SimTime now) const;
  bool output(int n) const { return outputs_[static_cast<std::size_t>(n - 3)]; }
  void set_input(int n, bool on) { inputs_[static_cast<std::size_t>(n - 1)] = on; }
  void set_analog(char channel, int value, SimTime now);
  void set_aux_inputs(int bits) { aux_inputs_ = bits & 0xff; }
  std::size_t queued() const { return queue_.size(); }
  const std::vector<std::string>& program() const { return program_; }

  struct Counters {
    std::uint64_t instructions = 0;
    std::uint64_t queries = 0;
    std::uint64_t rejects = 0;
    std::uint64_t kills = 0;
    std::uint64_t lost = 0;  // instructions dropped on a full queue
  };
  const Counters& counters() const { return counters_; }

 private:
  struct MotionItem {
    unsigned axes;  // 1 = X, 2 = Y
    SimTime queued_at;
    std::function<void(SimTime)> start;
  };

  bool run(const std::string& s, SimTime now, std::vector<std::string>& replies);
  bool query(const std::string& s, SimTime now, std::vector<std::string>& replies);
  bool axis_instruction(Axis& a, const std::string& rest, SimTime now);
  bool motion(const std::string& s, SimTime now);
  bool io_instruction(const std::string& s, SimTime now);
  void queue_motion(unsigned axes, SimTime now, std::function<void(SimTime)> start);
  void start_move(Axis& a, SimTime at, double target, double velocity, double acceleration);
  void start_speed(Axis& a, SimTime at, double velocity);
  void finish_moves(SimTime up_to, std::vector<std::string>& events);
  void quit(SimTime now);
  MoveLimits limits(const Axis& a) const;
  std::string time_of_day(SimTime now) const;
  std::string date() const;

  int number_;
  UnitSettings settings_;
  Axis x_{'X'};
  Axis y_{'Y'};
  double vector_base_ = 200, vector_max_ = 2000;
  std::array<bool, 2> inputs_{};
  std::array<bool, 2> outputs_{};
  bool in1_is_go_ = false;
  std::array<int, 4> analog_{128, 128, 0, 0};  // A\X, A\Y, A1, A2
  int aux_direction_ = 0xff;                   // 1 = input (P\I)
  int aux_outputs_ = 0, aux_inputs_ = 0;
  std::uint32_t ratio_yx_ = 0, ratio_xy_ = 0;
  int mode_ = 1;
  bool rts_overflow_ = false;
  bool warned_ = false;  // Q* sent, *Q not yet
  std::vector<std::string> program_;
  std::deque<MotionItem> queue_;
  SimTime clock_set_at_;
  int clock_seconds_ = 0;  // time of day when set
  int month_ = 1, day_ = 1, year_ = 0;
  Counters counters_;
};

}  // namespace fieldgate::sim::centent
