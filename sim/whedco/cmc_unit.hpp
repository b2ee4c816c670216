#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sim/common/motion_axis.hpp"
#include "sim/whedco/command.hpp"

namespace fieldgate::sim::whedco {

inline constexpr int kAxisFunctional = 8;  // §6.2 "Unit Functional"
inline constexpr std::string_view kAxisOrder = "XYWZ";

// CMC-0 faults (§6.1.2). The non-echo number is base * 256 + axis byte (README).
enum class UnitFault {
  functional = 0,
  power_failure = 1,
  axis_initialize = 2,
  arithmetic_overflow = 3
};

// Status words: the manual's §4.3.1 is missing from the excerpt; these layouts are the
// simulator's (and the model's) assumption, documented in README.md.
namespace status {
inline constexpr int busy = 1 << 0;             // RS: any axis moving or a profile running
inline constexpr int faulted = 1 << 1;          // RS: FC is not Unit Functional; RSa: axis faulted
inline constexpr int profile_running = 1 << 2;  // RS
inline constexpr int defining = 1 << 3;         // RS: between DEn and ED
inline constexpr int memory_lost = 1 << 7;      // RS: set by CB (§5.3.1)
inline constexpr int aux_enabled = 1 << 2;      // RSa: auxiliary position equation on (jog, search)
inline constexpr int homing = 1 << 3;           // RSa: SHZ/SIZ/SBZ search under way
inline constexpr int home_input = 1 << 4;       // RSa: the axis stands on its home input
}  // namespace status

// How RS/RSa print the status word (§4.3.1 is missing from the excerpt).
enum class StatusFormat { decimal, hex, binary };

struct UnitOptions {
  int address = 4;
  std::string axes = "WXYZ";   // axes present (CMC-1/CMC-2 modules on the link)
  std::string steppers;        // of those, CMC-1 steppers (no following error); others servo
  bool echo = true;            // SW2-5, factory setting echo
  bool power_failure = false;  // start with the power-up fault ("Power Failure")
  StatusFormat status_format = StatusFormat::decimal;  // "1538", "0602", "0000011000000010"
  // Non-echo FC: the base numbers are not in the excerpt. false: base x 256 + axis byte (base 0
  // Unit Functional, 1 Power Failure, 2 Axis Initialize, 3 Arithmetic Overflow); true: the FCa
  // code table read for FC too: 8 Unit Functional, 0 Power Failure, plus the axis byte.
  bool fc_table_codes = false;
  // `DEn` on an empty profile: only the prompt (every example) or `ED` (§5.17's text).
  bool de_answers_ed = false;
  // Servo lag between commanded and actual position.
  std::chrono::microseconds servo_lag{2000};
};

// One CMC-0 with its axes: parameters, motion, variables, I/O, faults and stored profiles.
// Everything is evaluated at the time the caller passes in.
class CmcUnit {
 public:
  CmcUnit(UnitOptions options, SimTime now);

  int address() const { return options_.address; }
  bool echo() const { return options_.echo; }
  void set_echo(bool on) { options_.echo = on; }
  bool online() const { return online_; }
  void set_online(bool on) { online_ = on; }

  // Runs one line (after the address, without CR) at `now` and returns what the unit prints
  // before its `*` prompt: empty, a value, a fault text or "?" for a line it refuses.
  std::string execute(std::string_view body, SimTime now);
  // Lets a running profile catch up to `now`.
  void advance(SimTime now);

  // Control channel and tests.
  bool inject_fault(char axis, int code, SimTime now);
  void power_cycle(SimTime now);
  void set_inputs(int mask) { input_levels_ = mask; }
  bool set_analog(int channel, int counts);
  bool set_home(char axis, double machine_position);
  bool define_profile(int number, const std::vector<std::string>& lines, std::string& error);
  bool has_axis(char axis) const;
  std::optional<double> commanded_position(char axis, SimTime now);
  int axis_fault(char axis) const;
  UnitFault unit_fault() const { return unit_fault_; }
  std::int32_t variable(int index) const { return variables_.at(static_cast<std::size_t>(index)); }
  bool profile_running() const { return !stack_.empty(); }
  int unit_status(SimTime now);
  int axis_status(char axis, SimTime now);
  int fault_number() const;  // FC as non-echo prints it

 private:
  struct Axis {
    bool present = false;
    bool stepper = false;
    MotionAxis motion{0.0};
    HomingSequence homing;
    double home_set_to = 0;
    double offset = 0;        // machine position = position + offset
    double home_machine = 0;  // where the home input is, machine coordinates
    int unit_ratio = 1;
    double absolute_move = 0;      // pp
    double incremental_move = 0;   // pp
    double acceleration = 80000;   // pp/s²
    double frequency = 0;          // FS, pp/s
    char multiplier_source = 'N';  // LM: N constant, V variable/256, A analog/256
    double multiplier = 0;
    int multiplier_index = 0;
    char input_source = 'F';  // LI: F frequency source, E external encoder (reads 0 here)
    double ellipse = 1;
    bool aux = false;
    int fault = kAxisFunctional;
    std::map<std::string, double> constants;
  };
  struct Frame {
    int profile = 0;
    std::size_t line = 0;
    long repeats = 0;
  };
  enum class Wait { none, time, motion, condition };

  Axis* axis(char letter);
  std::string run(const Command& c, SimTime t, bool from_profile);
  std::string query(const Command& c);
  void update_axes(SimTime t);
  bool busy(Axis& a, SimTime t);
  std::optional<SimTime> stop_time(Axis& a, SimTime from);
  bool start_run(const Command& c, SimTime t);
  void halt(SimTime t);
  void fault_axis(Axis& a, int code, SimTime t);
  void arithmetic_overflow();
  double user_to_internal(const Value& v, const Axis* scale_axis, double per_variable = 1.0) const;
  std::optional<std::int64_t> evaluate(std::string_view rhs, SimTime t, bool& overflow);
  bool condition_true(std::string_view text, SimTime t);
  int pin_level(int pin) const;
  double multiplier_of(const Axis& a) const;
  void start_profile(int number, SimTime t);
  std::string fault_text() const;
  std::string status_text(int word) const;  // RS/RSa as --status-format prints them
  std::string definition_line(std::string_view body);
  void reset_parameters();

  UnitOptions options_;
  bool online_ = true;
  std::map<char, Axis> axes_;
  UnitFault unit_fault_ = UnitFault::functional;
  bool memory_lost_ = false;
  std::array<std::int32_t, 16> variables_{};
  std::array<bool, 16> booleans_{};
  std::array<int, 4> analog_{};
  int input_levels_ = 0;    // levels applied to pins that are inputs, bit n-1 = I/O n
  int output_latches_ = 0;  // set by STId/RSId
  int output_pins_ = 0;     // pins made outputs by DRd0
  std::map<std::string, double> parameters_;  // VX VW VOX VOW RX RW PH* AD* AO* PE UE DG
  std::map<int, std::vector<std::string>> profiles_;
  std::optional<int> defining_;
  std::size_t edit_line_ = 0;
  // Profile execution.
  std::vector<Frame> stack_;
  Wait wait_ = Wait::none;
  SimTime wait_until_{};
  char wait_axis_ = 0;
  std::string wait_condition_;
  SimTime runner_time_{};
};

// Numbers as the unit prints them: up to four decimals, trailing zeros dropped.
std::string format_user_value(double value);

}  // namespace fieldgate::sim::whedco
