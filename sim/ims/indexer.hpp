#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sim/common/motion_axis.hpp"

// One IMS microstepper driver & indexer (shared/protocols/ims-indexer.md): the command set of §3
// as seen from the host, its parameters (working and saved copies), the EEPROM and the motion
// physics. The party line around it (names, echo, global characters) is party_line.hpp.
namespace fieldgate::sim::ims {

// The working parameters; `S` copies them to the saved set, reset and `C0` copy them back.
struct Parameters {
  int jog_slow = 3;  // B, x30 steps/s
  int jog_fast = 20;
  int divide = 0;                 // D
  int settle = 50;                // E, x10 ms
  int resolution = 0;             // H: 0 fixed (FR), 1 variable (VR)
  double initial_velocity = 400;  // I, steps/s
  int accel = 10;                 // K
  int decel = 10;
  double trip_position = 0;  // T
  int trip_address = 0;
  double slew = 2048;    // V as requested; motion uses achievable_rate(slew)
  int hold_current = 5;  // Y, %
  int run_current = 25;
  int limit_mode = 0;  // l
  // Encoder option parameters (d e h r s t v): stored, not simulated.
  int deadband = 30;
  int encoder_lines = 0;
  int hunt_resolution = 4;
  int retries = 5;
  int stall_factor = 20;
  int stall_interval = 5;
  int hunt_velocity = 700;
};

// Where the home switch reads high, in the physical frame (the position at power-up is 0).
struct HomeSwitch {
  double edge = -1000;
  bool high_below = true;  // high for positions <= edge; false: high for positions >= edge
};

// How a unit prints a result (the manual allows several readings, issue 20): padding, the line
// end, and when positions carry two decimals.
struct ResultFormat {
  enum class Padding { right_aligned, space, none };  // "   1000", " 1000", "1000"
  enum class Decimals { variable_resolution, always, never };
  Padding padding = Padding::right_aligned;
  std::string end = "\r\n";
  // variable_resolution: "12.50" only in VR with a fraction (as [Z] reads); always: "1000.00"
  // in every mode ([Z] prints two decimals); never: whole numbers (p.12).
  Decimals decimals = Decimals::variable_resolution;
};

class Indexer {
 public:
  Indexer(char name, HomeSwitch home, SimTime now, ResultFormat format = {});

  char name() const { return name_; }

  // What a command line (without name and terminator) produces.
  struct Outcome {
    enum class Kind { silent, completion, result };
    Kind kind = Kind::silent;
    std::string text;  // the result line(s), CR LF included (Kind::result)
    // The completion or result is late: a queued index, W, S, C.
    std::chrono::microseconds delay{0};
  };
  Outcome execute(std::string_view line, SimTime now);

  void hard_stop(SimTime now);  // ESC
  void soft_stop(SimTime now);  // @
  void reset(SimTime now);      // ^C or power cycle
  // The counter reads `value`, as if the jog inputs had moved the axis there.
  void set_position(SimTime now, double value);
  void set_limits(bool plus, bool minus) {
    limit_plus_ = plus;
    limit_minus_ = minus;
  }
  void set_inputs(int mask) { inputs_ = mask & 7; }

  double position(SimTime now);  // counts (FR microsteps or VR full steps)
  int status(SimTime now);       // `^`
  double step_rate(SimTime now);
  int outputs() const { return outputs_; }
  int eeprom_writes() const { return eeprom_writes_; }
  const Parameters& parameters() const { return params_; }
  const Parameters& saved_parameters() const { return saved_; }
  std::uint8_t nvm(int address) const { return nvm_.at(static_cast<std::size_t>(address)); }

  // The rate the step generator really runs at for a requested one (digest §5: V3000 -> 3004).
  static double achievable_rate(double requested);

 private:
  enum class HomePhase { idle, seek, creep };

  void update(SimTime now);
  MoveLimits limits(double velocity) const;
  double acceleration() const;
  double deceleration() const;
  bool home_high(SimTime now);
  void start_index(SimTime now, double target);
  void start_home(SimTime now, double speed, int direction);
  std::optional<SimTime> index_end(SimTime now) const;
  void store_parameters();
  std::string format_position(double value) const;
  std::string padded(const std::string& number) const;

  char name_;
  HomeSwitch home_;
  ResultFormat format_;
  MotionAxis motion_;
  double origin_ = 0;  // physical position of count 0
  bool index_running_ = false;
  std::optional<double> queued_target_;
  SimTime queued_start_{};  // when the running index ends and the queued one starts
  HomePhase home_phase_ = HomePhase::idle;
  double creep_target_ = 0;
  bool limit_plus_ = false;
  bool limit_minus_ = false;
  int inputs_ = 0;
  int outputs_ = 0;
  Parameters params_;
  Parameters saved_;
  std::array<std::uint8_t, 2048> nvm_{};
  int eeprom_writes_ = 0;
};

}  // namespace fieldgate::sim::ims
