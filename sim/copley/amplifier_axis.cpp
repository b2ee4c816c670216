#include "sim/copley/amplifier_axis.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

namespace fieldgate::sim::copley {
namespace {

// 0xa4 bits 0 (flash CRC) and 1 (internal error) cannot be cleared.
constexpr std::uint32_t kFatalFaults = 0x3;
// Simplified homing: the reference is found this far from the start, in the method's direction.
constexpr double kHomeSearchCounts = 1000.0;
// Servo following error: the actual position trails the trajectory by this much time.
constexpr double kServoLagSeconds = 0.001;
// Motor current per trajectory acceleration, in 0.01 A per count/s^2.
constexpr double kCurrentPerAcceleration = 1.0 / 1000.0;
// A limit of 0 in the velocity loop means "no limit".
constexpr double kUnlimitedRate = 1e12;
constexpr std::int64_t kBusVoltage = 480;  // 48.0 V
constexpr double kAmbientCelsius = 30.0;
constexpr double kCountsPerElectricalCycle = 1000.0;
// UART clock the achievable baud rates derive from (divisor = clock / baud).
constexpr double kUartClock = 9'375'000.0;
constexpr std::uint32_t kMinBaud = 9600;
constexpr std::uint32_t kMaxBaud = 115200;

constexpr std::array kHomingMethods = {512, 544, 560, 513, 529, 545, 561, 516, 532, 548,
                                       564, 514, 530, 546, 562, 610, 626, 771, 787, 515,
                                       531, 803, 819, 867, 883, 547, 563, 611, 627};

bool position_state(int state) {
  return (state >= 21 && state <= 25) || state == 30 || (state >= 31 && state <= 35) || state == 40;
}
bool programmed_position(int state) {
  return state == 21 || state == 31;
}

double rate_or_unlimited(double rate) {
  return rate > 0 ? rate : kUnlimitedRate;
}

}  // namespace

bool AmplifierAxis::valid_state(int state, bool stepper) {
  static constexpr std::array kServo = {0, 1, 2, 3, 4, 5, 11, 12, 13, 14, 21, 22, 23, 24, 25, 30};
  static constexpr std::array kMicrostep = {31, 33, 34, 35, 40, 42};
  if (std::find(kServo.begin(), kServo.end(), state) != kServo.end()) return true;
  // A servo amplifier has no microstepping states; a stepper (Stepnet) can also run servo
  // states with an encoder, so it accepts both.
  return stepper && std::find(kMicrostep.begin(), kMicrostep.end(), state) != kMicrostep.end();
}

std::uint32_t AmplifierAxis::achievable_baud(std::uint32_t requested) {
  const double divisor = std::round(kUartClock / requested);
  return static_cast<std::uint32_t>(std::lround(kUartClock / divisor));
}

AmplifierAxis::AmplifierAxis(bool stepper, SimTime now) : stepper_(stepper) {
  for (const VariableInfo& info : variable_catalog()) {
    if (info.in_flash) flash_[info.id] = info.defaults;
  }
  power_up(now);
}

std::int32_t AmplifierAxis::ram(int id, std::size_t index) const {
  const auto it = ram_.find(id);
  return it != ram_.end() && index < it->second.size() ? it->second[index] : 0;
}

void AmplifierAxis::power_up(SimTime now) {
  const std::uint32_t fatal = static_cast<std::uint32_t>(ram(var::fault_register)) & kFatalFaults;
  ram_.clear();
  for (const VariableInfo& info : variable_catalog()) {
    if (!info.in_ram || info.access != Access::read_write) continue;
    ram_[info.id] = info.in_flash ? flash_[info.id] : info.defaults;
  }
  ram_[var::baud_rate] = {static_cast<std::int32_t>(achievable_baud(kMinBaud))};
  ram_[var::fault_register] = {static_cast<std::int32_t>(fatal)};
  motion_ = MotionAxis(0.0);
  homing_.clear();
  referenced_ = homing_error_ = aborted_ = profile_move_ = s_curve_ = false;
  ramp_ = {};
  state_ = 0;
  enter_state(ram(var::desired_state), now);
}

void AmplifierAxis::update(SimTime now) {
  if (homing_.searching() && homing_.update(motion_, now) == HomingSequence::Phase::succeeded) {
    referenced_ = true;
  }
}

std::variant<Values, Error> AmplifierAxis::get(Bank bank, int id, SimTime now) {
  const VariableInfo* info = find_variable(id);
  if (info == nullptr) return Error::unknown_variable;
  if (bank == Bank::flash ? !info->in_flash : !info->in_ram) return Error::wrong_bank;
  update(now);
  if (bank == Bank::flash) {
    const auto& stored = flash_.at(id);
    return Values(stored.begin(), stored.end());
  }
  if (info->access != Access::read_write) return Values{monitor_value(id, now)};
  const auto& stored = ram_.at(id);
  return Values(stored.begin(), stored.end());
}

std::optional<Error> AmplifierAxis::set(Bank bank, int id, std::span<const std::int64_t> values,
                                        SimTime now) {
  const VariableInfo* info = find_variable(id);
  if (info == nullptr) return Error::unknown_variable;
  if (bank == Bank::flash ? !info->in_flash : !info->in_ram) return Error::wrong_bank;
  if (info->access != Access::read_write) return Error::read_only;
  if (values.size() < info->value_count()) return Error::not_enough_data;
  if (values.size() > info->value_count()) return Error::too_much_data;

  std::vector<std::int32_t> words;
  for (const std::int64_t v : values) {
    // Hex patterns such as 0xfff60001 are 32-bit words, stored as their two's-complement value.
    if (v < std::numeric_limits<std::int32_t>::min() ||
        v > std::numeric_limits<std::uint32_t>::max()) {
      return Error::out_of_range;
    }
    words.push_back(static_cast<std::int32_t>(static_cast<std::uint32_t>(v)));
  }
  if (id == var::desired_state && !valid_state(words[0], stepper_)) return Error::bad_axis_state;
  if (id == var::baud_rate && (values[0] < kMinBaud || values[0] > kMaxBaud)) {
    return Error::out_of_range;
  }
  if (bank == Bank::flash) {
    // Saving 0x24 = 0 is legal here as on the amplifier, even though CME 2 then considers the
    // amplifier unprogrammed.
    flash_[id] = std::move(words);
    return std::nullopt;
  }
  update(now);
  write_ram(id, std::move(words), now);
  return std::nullopt;
}

std::optional<Error> AmplifierAxis::copy(Bank source, int id, SimTime now) {
  const VariableInfo* info = find_variable(id);
  if (info == nullptr) return Error::unknown_variable;
  if (!info->in_ram || !info->in_flash) return Error::wrong_bank;
  if (source == Bank::ram) {
    flash_[id] = ram_[id];
    return std::nullopt;
  }
  update(now);
  write_ram(id, flash_[id], now);
  return std::nullopt;
}

void AmplifierAxis::write_ram(int id, std::vector<std::int32_t> words, SimTime now) {
  switch (id) {
    case var::fault_register: {
      const bool was_faulted = faulted();
      const auto clear = static_cast<std::uint32_t>(words[0]) & ~kFatalFaults;
      ram_[id][0] = static_cast<std::int32_t>(static_cast<std::uint32_t>(ram(id)) & ~clear);
      if (was_faulted && !faulted()) resume(now);
      return;
    }
    case var::digital_outputs: {
      // Only outputs configured for program control (0x70–0x77 first word 2 or 258) follow.
      std::uint32_t programmable = 0;
      for (int k = 0; k < 8; ++k) {
        if ((ram(var::output_config_first + k) & 0xff) == 2) programmable |= 1u << k;
      }
      const auto old = static_cast<std::uint32_t>(ram(id));
      const auto requested = static_cast<std::uint32_t>(words[0]);
      ram_[id][0] = static_cast<std::int32_t>((old & ~programmable) | (requested & programmable));
      return;
    }
    case var::baud_rate:
      ram_[id][0] =
          static_cast<std::int32_t>(achievable_baud(static_cast<std::uint32_t>(words[0])));
      return;
    case var::desired_state:
      ram_[id] = words;
      enter_state(words[0], now);
      return;
    default:
      break;
  }
  ram_[id] = std::move(words);
  if (!output_enabled()) return;
  if (state_ == 11 && (id == var::programmed_velocity || id == var::velocity_accel ||
                       id == var::velocity_decel || id == var::velocity_limit)) {
    apply_velocity_command(now);  // §3.3.1: a new 0x2f applies directly, no t command
  }
  if (state_ == 1 && id == var::programmed_current) start_current_ramp(now);
}

void AmplifierAxis::enter_state(int state, SimTime now) {
  update(now);
  const int old = state_;
  state_ = state;
  if (old == state) {
    if (state == 11) apply_velocity_command(now);
    return;
  }
  halt(now);
  ramp_ = {};
  if (!output_enabled()) return;
  if (state == 1) start_current_ramp(now);
  if (state == 11) apply_velocity_command(now);
}

void AmplifierAxis::halt(SimTime now) {
  // Disabling or faulting the output: the trajectory ends where it is, homing fails.
  if (homing_.searching()) {
    homing_.fail();
    homing_error_ = true;
  }
  motion_.stop(now);
  profile_move_ = false;
}

void AmplifierAxis::resume(SimTime now) {
  if (!output_enabled()) return;
  if (state_ == 1) {
    ramp_ = {};
    start_current_ramp(now);
  }
  if (state_ == 11) apply_velocity_command(now);
}

void AmplifierAxis::apply_velocity_command(SimTime now) {
  if (!output_enabled()) return;
  const double limit = ram(var::velocity_limit) / 100.0;  // 0x3a is in 0.01 counts/s
  double velocity = ram(var::programmed_velocity) / 10.0;
  if (limit > 0) velocity = std::clamp(velocity, -limit, limit);
  motion_.start_velocity(now, velocity, rate_or_unlimited(ram(var::velocity_accel) * 1000.0),
                         rate_or_unlimited(ram(var::velocity_decel) * 1000.0));
  profile_move_ = false;
}

void AmplifierAxis::start_current_ramp(SimTime now) {
  ramp_ = {current(now), static_cast<double>(ram(var::programmed_current)),
           ram(var::current_ramp) / 10.0, now};
}

double AmplifierAxis::current(SimTime now) const {
  if (!output_enabled()) return 0.0;
  if (state_ == 1) {
    if (ramp_.rate <= 0) return ramp_.to;
    const double elapsed = std::chrono::duration<double>(now - ramp_.start).count();
    const double step = ramp_.rate * elapsed;
    return ramp_.to > ramp_.from ? std::min(ramp_.to, ramp_.from + step)
                                 : std::max(ramp_.to, ramp_.from - step);
  }
  // Analog and PWM command inputs read zero in the simulator.
  if (state_ >= 2 && state_ <= 5) return 0.0;
  const double peak = ram(var::peak_current);
  return std::clamp(motion_.acceleration(now) * kCurrentPerAcceleration, -peak, peak);
}

bool AmplifierAxis::soft_limits_enabled() const {
  return ram(var::positive_limit) > ram(var::negative_limit);
}

std::optional<Error> AmplifierAxis::trajectory(int sub_command, SimTime now) {
  update(now);
  switch (sub_command) {
    case 0:
      abort_motion(now);
      return std::nullopt;
    case 1:
      return start_move(now);
    default:
      return start_homing(now);
  }
}

void AmplifierAxis::abort_motion(SimTime now) {
  if (!motion_.in_motion(now) || !(profile_move_ || homing_.searching())) return;
  if (homing_.searching()) {
    homing_.fail();
    homing_error_ = true;
  }
  motion_.abort(now, rate_or_unlimited(ram(var::abort_deceleration) * 10.0));
  aborted_ = true;
  profile_move_ = true;  // the generator is producing the stopping ramp
  s_curve_ = false;
}

std::optional<Error> AmplifierAxis::start_move(SimTime now) {
  // The manual gives no error for a move while disabled, faulted or outside a position mode;
  // e 14 "Unknown axis state" is the closest code.
  if (!output_enabled() || !position_state(state_)) return Error::bad_axis_state;
  // Analog, digital and CANopen position modes: t 1 only makes new limits effective (§3.4.3).
  if (!programmed_position(state_)) return std::nullopt;
  if (homing_.searching()) return Error::moving;

  const int profile = ram(var::profile_type);
  if (profile != 0 && profile != 1 && profile != 2 && profile != 256 && profile != 257) {
    return Error::bad_trajectory_mode;
  }
  const bool s_curve = profile == 1 || profile == 257;
  const double velocity = ram(var::max_velocity) / 10.0;
  const double acceleration = ram(var::max_acceleration) * 10.0;
  // S-curve moves run as trapezoids here, with 0xcc for both ramps as the S-curve would.
  const double deceleration = s_curve ? acceleration : ram(var::max_deceleration) * 10.0;
  if (motion_.in_motion(now) && (s_curve || s_curve_)) return Error::moving;
  if (velocity < 0 || (velocity == 0 && profile != 2)) return Error::bad_velocity;
  if (acceleration <= 0) return Error::bad_acceleration;
  if (deceleration <= 0) return Error::bad_deceleration;
  if (s_curve && ram(var::max_jerk) <= 0) return Error::bad_jerk;

  const double low = ram(var::negative_limit);
  const double high = ram(var::positive_limit);
  const MoveLimits limits{velocity, acceleration, deceleration};
  if (profile == 2) {
    const int direction =
        ram(var::position_command) > 0 ? 1 : (ram(var::position_command) < 0 ? -1 : 0);
    if (direction == 0 || velocity == 0) {
      motion_.start_velocity(now, 0.0, acceleration, deceleration);
    } else if (soft_limits_enabled()) {
      motion_.start_move(now, direction > 0 ? high : low, limits);
    } else {
      motion_.start_velocity(now, direction * velocity, acceleration, deceleration);
    }
  } else {
    double target = ram(var::position_command);
    // Relative moves count from the end of the move in progress (the current position at rest).
    if (profile >= 256) target += motion_.rest_position(now);
    if (soft_limits_enabled()) target = std::clamp(target, low, high);
    motion_.start_move(now, target, limits);
  }
  aborted_ = false;
  profile_move_ = true;
  s_curve_ = s_curve;
  return std::nullopt;
}

std::optional<Error> AmplifierAxis::start_homing(SimTime now) {
  if (!output_enabled() || !programmed_position(state_)) return Error::bad_axis_state;
  if (motion_.in_motion(now)) return Error::moving;
  referenced_ = homing_error_ = aborted_ = profile_move_ = false;
  const int method = ram(var::homing_method);
  if (method == 512) {  // set current position as home
    motion_.set_position(now, ram(var::home_offset));
    referenced_ = true;
    return std::nullopt;
  }
  const double velocity = ram(var::homing_fast_velocity) / 10.0;
  const double acceleration = ram(var::homing_acceleration) * 10.0;
  const bool known =
      std::find(kHomingMethods.begin(), kHomingMethods.end(), method) != kHomingMethods.end();
  if (!known || velocity <= 0 || acceleration <= 0) {
    // Accepted, and reported as failed through 0xc9 bit 11, as a sequence that cannot run.
    homing_error_ = true;
    return std::nullopt;
  }
  const double direction = (method & 0x010) != 0 ? -1.0 : 1.0;
  homing_.start(motion_, now, motion_.position(now) + direction * kHomeSearchCounts,
                {velocity, acceleration, acceleration}, ram(var::home_offset));
  return std::nullopt;
}

void AmplifierAxis::latch_faults(std::uint32_t bits, SimTime now) {
  update(now);
  const bool was_faulted = faulted();
  ram_[var::fault_register][0] =
      static_cast<std::int32_t>(static_cast<std::uint32_t>(ram(var::fault_register)) | bits);
  if (!was_faulted && faulted()) halt(now);
}

std::uint32_t AmplifierAxis::event_status(SimTime now) {
  update(now);
  std::uint32_t status = 0;
  if (state_ == 0) status |= (1u << 12) | (1u << 15);
  if (faulted()) status |= (1u << 22) | (1u << 15);
  if (motion_.in_motion(now)) status |= 1u << 27;
  if (soft_limits_enabled()) {
    const double position = motion_.position(now);
    if (position >= ram(var::positive_limit)) status |= 1u << 16;
    if (position <= ram(var::negative_limit)) status |= 1u << 17;
  }
  return status;
}

std::uint32_t AmplifierAxis::trajectory_status(SimTime now) {
  update(now);
  std::uint32_t status = 0;
  if (homing_error_) status |= 1u << 11;
  if (referenced_) status |= 1u << 12;
  if (homing_.searching()) status |= 1u << 13;
  if (aborted_) status |= 1u << 14;
  if (profile_move_ && motion_.in_motion(now)) status |= 1u << 15;
  return status;
}

std::int64_t AmplifierAxis::motor_position(SimTime now) {
  return monitor_value(var::motor_position, now);
}

std::int64_t AmplifierAxis::monitor_value(int id, SimTime now) {
  update(now);
  const double commanded = motion_.position(now);
  const double velocity = motion_.velocity(now);
  const double actual = stepper_ ? commanded : commanded - velocity * kServoLagSeconds;
  const double amps = current(now);
  const double electrical = 2 * std::numbers::pi *
                            std::fmod(std::abs(actual), kCountsPerElectricalCycle) /
                            kCountsPerElectricalCycle;
  switch (id) {
    case var::actual_current:
    case var::commanded_current:
    case var::limited_current:
      return std::llround(amps);
    case var::load_position:
    case var::motor_position:
      return std::llround(actual);
    case var::actual_velocity:
    case var::load_velocity:
    case var::commanded_velocity:
    case var::limited_velocity:
    case var::profile_velocity:
      return std::llround(velocity * 10.0);
    case var::sin_voltage:
      return std::llround(1000.0 * std::sin(electrical));
    case var::cos_voltage:
      return std::llround(1000.0 * std::cos(electrical));
    case var::bus_voltage:
      return kBusVoltage;
    case var::temperature:
      return std::llround(kAmbientCelsius + std::abs(amps) / 100.0);
    case var::commanded_position:
    case var::limited_position:
      return std::llround(commanded);
    case var::following_error:
      return std::llround(commanded) - std::llround(actual);
    case var::profile_acceleration:
      return std::llround(motion_.acceleration(now) / 10.0);
    case var::event_status:
      return event_status(now);
    case var::digital_inputs:
      return inputs_;
    case var::phase_angle:
      return std::llround(electrical * 180.0 / std::numbers::pi) % 360;
    case var::trajectory_status:
      return trajectory_status(now);
    default:  // analog input, velocity loop error: nothing drives them in the simulator
      return 0;
  }
}

}  // namespace fieldgate::sim::copley
