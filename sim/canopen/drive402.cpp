#include "drive402.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace fieldgate::sim::canopen {

namespace {

constexpr std::uint16_t kCwSwitchOn = 1 << 0;
constexpr std::uint16_t kCwEnableVoltage = 1 << 1;
constexpr std::uint16_t kCwQuickStop = 1 << 2;  // active low
constexpr std::uint16_t kCwEnableOperation = 1 << 3;
constexpr std::uint16_t kCwNewSetpoint = 1 << 4;  // homing: start homing
constexpr std::uint16_t kCwChangeImmediately = 1 << 5;
constexpr std::uint16_t kCwRelative = 1 << 6;
constexpr std::uint16_t kCwFaultReset = 1 << 7;
constexpr std::uint16_t kCwHalt = 1 << 8;

constexpr std::uint16_t kSwVoltageEnabled = 1 << 4;
constexpr std::uint16_t kSwQuickStop = 1 << 5;
constexpr std::uint16_t kSwRemote = 1 << 9;
constexpr std::uint16_t kSwTargetReached = 1 << 10;
constexpr std::uint16_t kSwBit12 = 1 << 12;  // setpoint acknowledge / homing attained
constexpr std::uint16_t kSwBit13 = 1 << 13;  // homing error

constexpr std::chrono::milliseconds kStep{1};  // integration step

enum class Command { disable_voltage, quick_stop, shutdown, switch_on, enable_operation };

// CiA 402 controlword command coding. Bit 7 is left out: only its rising edge means anything,
// so a master that keeps it set still gets its other commands executed.
Command decode(std::uint16_t cw) {
  if (!(cw & kCwEnableVoltage)) return Command::disable_voltage;
  if (!(cw & kCwQuickStop)) return Command::quick_stop;
  if (!(cw & kCwSwitchOn)) return Command::shutdown;
  if (!(cw & kCwEnableOperation)) return Command::switch_on;
  return Command::enable_operation;
}

bool rising(std::uint16_t old_cw, std::uint16_t cw, std::uint16_t bit) {
  return !(old_cw & bit) && (cw & bit);
}
bool falling(std::uint16_t old_cw, std::uint16_t cw, std::uint16_t bit) {
  return (old_cw & bit) && !(cw & bit);
}

double sign(double v) {
  return v < 0 ? -1.0 : 1.0;
}

bool supported_homing_method(std::int8_t m) {
  return (m >= 1 && m <= 14) || (m >= 17 && m <= 30) || m == 33 || m == 34 || m == 35 || m == 37;
}

}  // namespace

const char* to_string(DriveState state) {
  switch (state) {
    case DriveState::not_ready_to_switch_on:
      return "not ready to switch on";
    case DriveState::switch_on_disabled:
      return "switch on disabled";
    case DriveState::ready_to_switch_on:
      return "ready to switch on";
    case DriveState::switched_on:
      return "switched on";
    case DriveState::operation_enabled:
      return "operation enabled";
    case DriveState::quick_stop_active:
      return "quick stop active";
    case DriveState::fault_reaction_active:
      return "fault reaction active";
    case DriveState::fault:
      return "fault";
  }
  return "?";
}

void Drive402::reset(TimePoint now) {
  params = DriveParams{};
  state_ = DriveState::not_ready_to_switch_on;
  ready_at_ = now + config_.init_time;
  t_ = now;
  controlword_ = 0;
  motion_ = Motion::idle;
  vel_ = 0;
  target_ = pos_;
  setpoint_ack_ = false;
  buffered_.reset();
  halted_ = false;
  homing_ = HomingStatus::not_started;
}

std::optional<TimePoint> Drive402::deadline() const {
  if (state_ == DriveState::not_ready_to_switch_on) return ready_at_;
  return std::nullopt;
}

std::int32_t Drive402::position_actual() const {
  return static_cast<std::int32_t>(std::llround(pos_ + offset_));
}

std::int32_t Drive402::velocity_actual() const {
  return static_cast<std::int32_t>(std::llround(vel_));
}

std::uint16_t Drive402::statusword() const {
  std::uint16_t sw = 0;
  switch (state_) {
    case DriveState::not_ready_to_switch_on:
      return 0x0000;
    case DriveState::switch_on_disabled:
      sw = 0x0040 | kSwVoltageEnabled;
      break;
    case DriveState::ready_to_switch_on:
      sw = 0x0001 | kSwVoltageEnabled | kSwQuickStop;
      break;
    case DriveState::switched_on:
      sw = 0x0003 | kSwVoltageEnabled | kSwQuickStop;
      break;
    case DriveState::operation_enabled:
      sw = 0x0007 | kSwVoltageEnabled | kSwQuickStop;
      break;
    case DriveState::quick_stop_active:
      sw = 0x0007 | kSwVoltageEnabled;
      break;
    case DriveState::fault_reaction_active:
      sw = 0x000F | kSwVoltageEnabled;
      break;
    case DriveState::fault:
      sw = 0x0008 | kSwVoltageEnabled;
      break;
  }
  sw |= kSwRemote;
  if (params.mode == kModeHoming) {
    switch (homing_) {
      case HomingStatus::not_started:
      case HomingStatus::interrupted:
        // Interrupted by halt or bit 4 falling: "target reached" means the axis stands (CiA 402
        // homing-mode statusword, halt = 1: velocity 0), not that the halt was taken.
        if (motion_ == Motion::idle) sw |= kSwTargetReached;
        break;
      case HomingStatus::in_progress:
        break;
      case HomingStatus::attained:
        sw |= kSwTargetReached | kSwBit12;
        break;
      case HomingStatus::error:
        sw |= kSwBit13 | (vel_ == 0 ? kSwTargetReached : 0);
        break;
    }
  } else {
    if (motion_ == Motion::idle && !buffered_) sw |= kSwTargetReached;
    if (params.mode == kModeProfilePosition && setpoint_ack_) sw |= kSwBit12;
  }
  return sw;
}

void Drive402::enter(DriveState next) {
  if (next == state_) return;
  if (log) log(fmt::format("402 {} -> {}", to_string(state_), to_string(next)));
  state_ = next;
  switch (next) {
    case DriveState::operation_enabled:
      target_ = pos_;
      setpoint_ack_ = false;
      buffered_.reset();
      halted_ = false;
      break;
    case DriveState::quick_stop_active:
    case DriveState::fault_reaction_active:
      break;
    default:
      // Power stage off: the motor stops following the trajectory at once.
      motion_ = Motion::idle;
      vel_ = 0;
      buffered_.reset();
      halted_ = false;
      if (homing_ == HomingStatus::in_progress) homing_ = HomingStatus::interrupted;
      break;
  }
}

void Drive402::advance(TimePoint now) {
  if (state_ == DriveState::not_ready_to_switch_on && now >= ready_at_)
    enter(DriveState::switch_on_disabled);
  while (t_ < now) {
    if (motion_ == Motion::idle) {
      t_ = now;
      break;
    }
    const Clock::duration slice = std::min<Clock::duration>(kStep, now - t_);
    t_ += slice;
    if (step(std::chrono::duration<double>(slice).count())) motion_done();
  }
}

bool Drive402::step(double dt) {
  switch (motion_) {
    case Motion::idle:
      return false;
    case Motion::stop: {
      const double speed = std::max(0.0, std::abs(vel_) - dec_ * dt);
      pos_ += sign(vel_) * (std::abs(vel_) + speed) / 2 * dt;
      vel_ = sign(vel_) * speed;
      if (speed > 0) return false;
      vel_ = 0;
      motion_ = Motion::idle;
      return true;
    }
    case Motion::position:
    case Motion::homing: {
      const double distance = goal_ - pos_;
      const double dir = sign(distance);
      if (vel_ * dir < 0) {  // moving away from the goal: brake first
        const double speed = std::max(0.0, std::abs(vel_) - dec_ * dt);
        pos_ += sign(vel_) * (std::abs(vel_) + speed) / 2 * dt;
        vel_ = sign(vel_) * speed;
        return false;
      }
      const double speed = std::abs(vel_);
      double next =
          speed > vmax_ ? std::max(vmax_, speed - dec_ * dt) : std::min(vmax_, speed + acc_ * dt);
      // Never faster than what still stops at the goal with the deceleration.
      next = std::min(next, std::max(std::sqrt(2 * dec_ * std::abs(distance)), speed - dec_ * dt));
      if (next * dt >= std::abs(distance)) {
        pos_ = goal_;
        vel_ = 0;
        motion_ = Motion::idle;
        return true;
      }
      pos_ += dir * next * dt;
      vel_ = dir * next;
      return false;
    }
  }
  return false;
}

void Drive402::motion_done() {
  switch (state_) {
    case DriveState::fault_reaction_active:
      enter(DriveState::fault);
      return;
    case DriveState::quick_stop_active:
      if (params.quick_stop_option >= 1 && params.quick_stop_option <= 4)
        enter(DriveState::switch_on_disabled);
      return;
    case DriveState::operation_enabled:
      break;
    default:
      return;
  }
  if (params.mode == kModeHoming) {
    if (homing_ == HomingStatus::in_progress) {
      offset_ = params.home_offset - pos_;
      target_ = pos_;
      homing_ = HomingStatus::attained;
      if (log) log(fmt::format("homing attained, position {}", position_actual()));
    }
    return;
  }
  if (params.mode == kModeProfilePosition && !halted_ && buffered_) {
    const double next = *buffered_;
    buffered_.reset();
    start_position(next);
    if (!(controlword_ & kCwNewSetpoint)) setpoint_ack_ = false;
  }
}

void Drive402::start_position(double raw_goal) {
  goal_ = raw_goal;
  vmax_ = std::max<double>(1, params.profile_velocity);
  acc_ = std::max<double>(1, params.profile_acceleration);
  dec_ = std::max<double>(1, params.profile_deceleration);
  motion_ = Motion::position;
}

void Drive402::start_stop(double deceleration) {
  if (motion_ == Motion::idle && vel_ == 0) return;
  dec_ = std::max(1.0, deceleration);
  motion_ = Motion::stop;
}

void Drive402::fault(TimePoint now) {
  advance(now);
  if (state_ == DriveState::fault || state_ == DriveState::fault_reaction_active) return;
  const bool was_moving = motion_ != Motion::idle && (state_ == DriveState::operation_enabled ||
                                                      state_ == DriveState::quick_stop_active);
  buffered_.reset();
  if (homing_ == HomingStatus::in_progress) homing_ = HomingStatus::error;
  enter(DriveState::fault_reaction_active);
  if (was_moving) {
    start_stop(params.quick_stop_deceleration);
  } else {
    motion_ = Motion::idle;
    vel_ = 0;
    enter(DriveState::fault);
  }
}

SdoAbort Drive402::set_mode(std::int8_t mode, TimePoint now) {
  if (mode != kModeNone && mode != kModeProfilePosition && mode != kModeHoming)
    return SdoAbort::value_range;
  advance(now);
  if (mode == params.mode) return SdoAbort::none;
  if (motion_ == Motion::position || motion_ == Motion::homing)
    start_stop(params.profile_deceleration);
  if (homing_ == HomingStatus::in_progress) homing_ = HomingStatus::interrupted;
  buffered_.reset();
  setpoint_ack_ = false;
  halted_ = false;
  params.mode = mode;
  return SdoAbort::none;
}

bool Drive402::set_controlword(std::uint16_t cw, TimePoint now) {
  advance(now);
  const std::uint16_t old_cw = controlword_;
  controlword_ = cw;
  if (rising(old_cw, cw, kCwFaultReset) && state_ == DriveState::fault) {
    homing_ = HomingStatus::not_started;
    enter(DriveState::switch_on_disabled);
    return true;
  }
  apply_command(cw);
  if (state_ == DriveState::operation_enabled) operation_mode_bits(old_cw, cw);
  return false;
}

void Drive402::apply_command(std::uint16_t cw) {
  const Command cmd = decode(cw);
  switch (state_) {
    case DriveState::switch_on_disabled:
      if (cmd == Command::shutdown) enter(DriveState::ready_to_switch_on);
      break;
    case DriveState::ready_to_switch_on:
      if (cmd == Command::switch_on) enter(DriveState::switched_on);
      if (cmd == Command::enable_operation) {
        enter(DriveState::switched_on);
        enter(DriveState::operation_enabled);
      }
      if (cmd == Command::disable_voltage || cmd == Command::quick_stop)
        enter(DriveState::switch_on_disabled);
      break;
    case DriveState::switched_on:
      if (cmd == Command::enable_operation) enter(DriveState::operation_enabled);
      if (cmd == Command::shutdown) enter(DriveState::ready_to_switch_on);
      if (cmd == Command::disable_voltage || cmd == Command::quick_stop)
        enter(DriveState::switch_on_disabled);
      break;
    case DriveState::operation_enabled:
      if (cmd == Command::switch_on) enter(DriveState::switched_on);
      if (cmd == Command::shutdown) enter(DriveState::ready_to_switch_on);
      if (cmd == Command::disable_voltage) enter(DriveState::switch_on_disabled);
      if (cmd == Command::quick_stop) {
        if (params.quick_stop_option == 0) {
          enter(DriveState::switch_on_disabled);
          break;
        }
        buffered_.reset();
        if (homing_ == HomingStatus::in_progress) homing_ = HomingStatus::interrupted;
        enter(DriveState::quick_stop_active);
        const bool profile_ramp = params.quick_stop_option == 1 || params.quick_stop_option == 5;
        start_stop(profile_ramp ? params.profile_deceleration : params.quick_stop_deceleration);
        if (motion_ == Motion::idle) motion_done();
      }
      break;
    case DriveState::quick_stop_active:
      if (cmd == Command::disable_voltage) enter(DriveState::switch_on_disabled);
      if (cmd == Command::enable_operation && motion_ == Motion::idle &&
          params.quick_stop_option >= 5 && params.quick_stop_option <= 8)
        enter(DriveState::operation_enabled);
      break;
    case DriveState::not_ready_to_switch_on:
    case DriveState::fault_reaction_active:
    case DriveState::fault:
      break;
  }
}

void Drive402::halt_motion() {
  if (motion_ == Motion::position || motion_ == Motion::homing)
    start_stop(params.profile_deceleration);
}

void Drive402::operation_mode_bits(std::uint16_t old_cw, std::uint16_t cw) {
  const bool halt = cw & kCwHalt;
  if (params.mode == kModeProfilePosition) {
    if (halt && !halted_) {
      halted_ = true;
      halt_motion();
    } else if (!halt && halted_) {
      halted_ = false;
      if (pos_ != target_) start_position(target_);
    }
    if (rising(old_cw, cw, kCwNewSetpoint))
      new_setpoint(cw & kCwChangeImmediately, cw & kCwRelative);
    if (falling(old_cw, cw, kCwNewSetpoint) && !buffered_) setpoint_ack_ = false;
  } else if (params.mode == kModeHoming) {
    if (rising(old_cw, cw, kCwNewSetpoint) && !halt) {
      start_homing();
    } else if (homing_ == HomingStatus::in_progress &&
               (halt || falling(old_cw, cw, kCwNewSetpoint))) {
      homing_ = HomingStatus::interrupted;
      halt_motion();
    }
  }
}

void Drive402::new_setpoint(bool change_immediately, bool relative) {
  const bool busy = motion_ == Motion::position;
  if (busy && !change_immediately && buffered_) return;  // buffer full: not acknowledged
  // A relative target counts from the preceding target, not from the actual position.
  const double base = buffered_ ? *buffered_ : target_;
  const double goal = relative ? base + params.target_position : params.target_position - offset_;
  target_ = goal;
  setpoint_ack_ = true;
  if (busy && !change_immediately) {
    buffered_ = goal;
    return;
  }
  buffered_.reset();
  if (!halted_) start_position(goal);
}

void Drive402::start_homing() {
  buffered_.reset();
  const std::int8_t method = params.homing_method;
  if (!supported_homing_method(method)) {
    homing_ = HomingStatus::error;
    if (log) log(fmt::format("homing method {} not supported", method));
    return;
  }
  if (method == 35 || method == 37) {
    offset_ = params.home_offset - pos_;
    target_ = pos_;
    homing_ = HomingStatus::attained;
    return;
  }
  homing_ = HomingStatus::in_progress;
  goal_ = config_.home_switch;
  vmax_ = std::max<double>(1, params.homing_speed_switch);
  acc_ = std::max<double>(1, params.homing_acceleration);
  dec_ = acc_;
  motion_ = Motion::homing;
}

}  // namespace fieldgate::sim::canopen
