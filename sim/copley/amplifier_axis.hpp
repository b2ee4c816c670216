#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <variant>
#include <vector>

#include "sim/common/motion_axis.hpp"
#include "sim/copley/protocol.hpp"
#include "sim/copley/variables.hpp"

namespace fieldgate::sim::copley {

using Values = std::vector<std::int64_t>;

// One axis of a Copley amplifier: its RAM and flash variables, operating mode (0x24), status
// registers and the motion physics behind the monitor variables.
//
// Time is passed in; the axis never reads a clock. Every call first brings the axis up to `now`
// (e.g. finishes a homing sequence whose travel has ended).
class AmplifierAxis {
 public:
  AmplifierAxis(bool stepper, SimTime now);

  std::variant<Values, Error> get(Bank bank, int id, SimTime now);
  std::optional<Error> set(Bank bank, int id, std::span<const std::int64_t> values, SimTime now);
  // `source` is the bank copied from: c r… saves RAM to flash, c f… restores RAM from flash.
  std::optional<Error> copy(Bank source, int id, SimTime now);
  // t 0 abort, t 1 start/update move, t 2 home.
  std::optional<Error> trajectory(int sub_command, SimTime now);

  // Reset or power cycle: RAM reloaded from flash, position zero, not referenced.
  void power_up(SimTime now);
  // Latches fault register bits (control channel), as the drive's fault detection would.
  void latch_faults(std::uint32_t bits, SimTime now);
  void set_inputs(std::uint32_t mask) { inputs_ = mask; }

  std::uint32_t event_status(SimTime now);
  std::uint32_t trajectory_status(SimTime now);
  std::int64_t motor_position(SimTime now);
  int desired_state() const { return state_; }

  static bool valid_state(int state, bool stepper);
  // The rate the UART really runs at for a requested baud: 0x90 reads back this value.
  static std::uint32_t achievable_baud(std::uint32_t requested);

 private:
  std::int32_t ram(int id, std::size_t index = 0) const;
  bool faulted() const { return ram(var::fault_register) != 0; }
  bool output_enabled() const { return state_ != 0 && !faulted(); }

  void update(SimTime now);
  std::int64_t monitor_value(int id, SimTime now);
  void write_ram(int id, std::vector<std::int32_t> values, SimTime now);
  void enter_state(int state, SimTime now);
  void halt(SimTime now);
  void resume(SimTime now);
  void apply_velocity_command(SimTime now);
  void start_current_ramp(SimTime now);
  double current(SimTime now) const;
  std::optional<Error> start_move(SimTime now);
  std::optional<Error> start_homing(SimTime now);
  void abort_motion(SimTime now);
  bool soft_limits_enabled() const;

  struct CurrentRamp {
    double from = 0;  // 0.01 A
    double to = 0;
    double rate = 0;  // 0.01 A/s; 0 = step
    SimTime start{};
  };

  bool stepper_;
  std::map<int, std::vector<std::int32_t>> ram_;
  std::map<int, std::vector<std::int32_t>> flash_;
  int state_ = 0;
  MotionAxis motion_;
  HomingSequence homing_;
  bool referenced_ = false;
  bool homing_error_ = false;
  bool aborted_ = false;
  bool profile_move_ = false;  // the motion was started by t 1 (0xc9 bit 15)
  bool s_curve_ = false;
  CurrentRamp ramp_;
  std::uint32_t inputs_ = 0;
};

}  // namespace fieldgate::sim::copley
