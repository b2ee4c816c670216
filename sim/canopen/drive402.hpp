// CiA 402 drive of one simulated node: the power state machine, profile position mode with the
// new-setpoint handshake, homing mode, and trapezoidal motion integrated over injected time.
#pragma once

#include "can_frame.hpp"
#include "object_dictionary.hpp"

#include <cstdint>
#include <optional>

namespace fieldgate::sim::canopen {

enum class DriveState {
  not_ready_to_switch_on,
  switch_on_disabled,
  ready_to_switch_on,
  switched_on,
  operation_enabled,
  quick_stop_active,
  fault_reaction_active,
  fault,
};
const char* to_string(DriveState state);

enum class HomingStatus { not_started, in_progress, interrupted, attained, error };

// Objects 0x6040..0x609A that a master writes; units are encoder counts, counts/s, counts/s².
struct DriveParams {
  std::int16_t quick_stop_option = 2;              // 0x605A
  std::int8_t mode = 0;                            // 0x6060
  std::int32_t target_position = 0;                // 0x607A
  std::int32_t home_offset = 0;                    // 0x607C
  std::uint32_t profile_velocity = 10000;          // 0x6081
  std::uint32_t profile_acceleration = 50000;      // 0x6083
  std::uint32_t profile_deceleration = 50000;      // 0x6084
  std::uint32_t quick_stop_deceleration = 200000;  // 0x6085
  std::int8_t homing_method = 35;                  // 0x6098
  std::uint32_t homing_speed_switch = 5000;        // 0x6099:1
  std::uint32_t homing_speed_zero = 1000;          // 0x6099:2
  std::uint32_t homing_acceleration = 50000;       // 0x609A
};

struct DriveConfig {
  std::chrono::milliseconds init_time{20};  // not ready to switch on -> switch on disabled
  double home_switch = -1000;               // raw position of the simulated home switch
};

class Drive402 {
 public:
  static constexpr std::int8_t kModeNone = 0;
  static constexpr std::int8_t kModeProfilePosition = 1;
  static constexpr std::int8_t kModeHoming = 6;

  explicit Drive402(DriveConfig config = {}) : config_(config) {}

  // Power-on or NMT reset node: parameters to defaults, state machine from the start. The
  // actual position is kept, as the motor does not move while the drive restarts.
  void reset(TimePoint now);
  void advance(TimePoint now);

  // Returns true when the write reset a fault (rising edge of bit 7 in Fault).
  bool set_controlword(std::uint16_t controlword, TimePoint now);
  SdoAbort set_mode(std::int8_t mode, TimePoint now);
  // Transition 13: fault reaction (quick stop ramp when moving), then Fault.
  void fault(TimePoint now);

  DriveState state() const { return state_; }
  std::uint16_t controlword() const { return controlword_; }
  std::uint16_t statusword() const;
  std::int8_t mode_display() const { return params.mode; }
  std::int32_t position_actual() const;
  std::int32_t velocity_actual() const;
  HomingStatus homing_status() const { return homing_; }
  bool moving() const { return motion_ != Motion::idle; }
  std::optional<TimePoint> deadline() const;

  DriveParams params;
  LogSink log;

 private:
  enum class Motion { idle, position, stop, homing };

  void enter(DriveState next);
  void apply_command(std::uint16_t cw);
  void operation_mode_bits(std::uint16_t old_cw, std::uint16_t cw);
  void new_setpoint(bool change_immediately, bool relative);
  void start_homing();
  void start_position(double raw_goal);
  void start_stop(double deceleration);
  void halt_motion();
  bool step(double dt);
  void motion_done();

  DriveConfig config_;
  DriveState state_ = DriveState::not_ready_to_switch_on;
  TimePoint ready_at_{};
  TimePoint t_{};
  std::uint16_t controlword_ = 0;

  Motion motion_ = Motion::idle;
  double pos_ = 0;     // raw counts
  double offset_ = 0;  // position actual = raw + offset
  double vel_ = 0;
  double goal_ = 0;  // raw goal of a position or homing move
  double vmax_ = 0, acc_ = 0, dec_ = 0;

  // Profile position mode.
  double target_ = 0;  // raw endpoint of the latest accepted setpoint
  bool setpoint_ack_ = false;
  std::optional<double> buffered_;  // raw goal waiting for the current move to end
  bool halted_ = false;

  HomingStatus homing_ = HomingStatus::not_started;
};

}  // namespace fieldgate::sim::canopen
