#include "sim/ims/indexer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <utility>

namespace fieldgate::sim::ims {
namespace {

// A ramp slope of 0 means "no ramp": effectively instant.
constexpr double kInstant = 1e12;
// K is "steps per point on an internal 0-500 point curve" (§3); the simulator reads it as
// 500 steps/s² per unit of K.
constexpr double kRampPerK = 500.0;
constexpr double kMaxPosition = 8'388'607.99;

// Encoder option parameters (d e h r s t v): stored as sent, not simulated.
constexpr std::array<std::pair<char, int Parameters::*>, 7> kEncoderParameters{{
    {'d', &Parameters::deadband},
    {'e', &Parameters::encoder_lines},
    {'h', &Parameters::hunt_resolution},
    {'r', &Parameters::retries},
    {'s', &Parameters::stall_factor},
    {'t', &Parameters::stall_interval},
    {'v', &Parameters::hunt_velocity},
}};

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

// `[+-]digits[.d[d]]`, the number syntax of §1; returns characters used, 0 if none.
std::size_t scan_number(std::string_view text, double& value) {
  std::size_t i = 0;
  double sign = 1;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) sign = text[i++] == '-' ? -1 : 1;
  const std::size_t start = i;
  double whole = 0;
  while (i < text.size() && is_digit(text[i]) && i - start < 10)
    whole = whole * 10 + (text[i++] - '0');
  if (i == start || (i < text.size() && is_digit(text[i]))) return 0;
  if (i < text.size() && text[i] == '.') {
    ++i;
    double scale = 0.1;
    const std::size_t fraction = i;
    while (i < text.size() && is_digit(text[i]) && i - fraction < 2) {
      whole += (text[i++] - '0') * scale;
      scale /= 10;
    }
    if (i == fraction || (i < text.size() && is_digit(text[i]))) return 0;
  }
  value = sign * whole;
  return i;
}

// Up to two numbers after the command character; the second needs a space before it.
std::optional<std::vector<double>> parse_fields(std::string_view text) {
  std::vector<double> fields;
  std::size_t i = 0;
  while (i < text.size()) {
    const std::size_t spaces = i;
    while (i < text.size() && text[i] == ' ') ++i;
    if (i == text.size()) break;
    if ((!fields.empty() && i == spaces) || fields.size() == 2) return std::nullopt;
    double v = 0;
    const std::size_t used = scan_number(text.substr(i), v);
    if (used == 0) return std::nullopt;
    fields.push_back(v);
    i += used;
  }
  return fields;
}

std::uint16_t velocity_word(double rate) {
  return static_cast<std::uint16_t>(
      std::clamp(65535.0 - std::round(1'228'800.0 / std::max(rate, 1.0)), 0.0, 65535.0));
}

}  // namespace

double Indexer::achievable_rate(double requested) {
  if (requested <= 0) return 0;
  const double divisor = std::max(1.0, std::floor(1'228'800.0 / requested));
  return 1'228'800.0 / divisor;
}

Indexer::Indexer(char name, HomeSwitch home, SimTime now, ResultFormat format)
    : name_(name), home_(home), format_(std::move(format)) {
  nvm_.fill(0xff);
  saved_ = params_;
  store_parameters();
  motion_.set_position(now, 0);
}

double Indexer::acceleration() const {
  return params_.accel == 0 ? kInstant : kRampPerK * params_.accel;
}

double Indexer::deceleration() const {
  return params_.decel == 0 ? kInstant : kRampPerK * params_.decel;
}

MoveLimits Indexer::limits(double velocity) const {
  return {std::max(1.0, velocity), acceleration(), deceleration()};
}

bool Indexer::home_high(SimTime now) {
  const double physical = motion_.position(now) + origin_;
  return home_.high_below ? physical <= home_.edge : physical >= home_.edge;
}

std::optional<SimTime> Indexer::index_end(SimTime now) const {
  if (motion_.velocity_move()) return std::nullopt;
  if (!motion_.in_motion(now)) return now;
  auto low = now;
  auto high = now + std::chrono::hours(24);
  if (motion_.in_motion(high)) return std::nullopt;
  for (int i = 0; i < 60 && high - low > std::chrono::microseconds(10); ++i) {
    const auto mid = low + (high - low) / 2;
    (motion_.in_motion(mid) ? low : high) = mid;
  }
  return high;
}

void Indexer::update(SimTime now) {
  if (queued_target_ && now >= queued_start_) {
    const double target = *queued_target_;
    queued_target_.reset();
    start_index(queued_start_, target);
  }
  if (home_phase_ != HomePhase::idle && !motion_.velocity_move() && !motion_.in_motion(now)) {
    if (home_phase_ == HomePhase::seek && motion_.position(now) != creep_target_) {
      // Left the high region: reverse and creep at I back onto the edge (§6).
      motion_.start_move(now, creep_target_, limits(params_.initial_velocity));
      home_phase_ = HomePhase::creep;
    } else {
      home_phase_ = HomePhase::idle;
    }
  }
  if (index_running_ && !motion_.in_motion(now)) index_running_ = false;
  const double v = motion_.velocity(now);
  if ((v > 0 && limit_plus_) || (v < 0 && limit_minus_)) {
    // Limit A stops +, B stops -; l2/l3 decelerate, l0/l1 stop at once (§3 `l`).
    if (params_.limit_mode >= 2)
      motion_.abort(now, deceleration());
    else
      motion_.stop(now);
    home_phase_ = HomePhase::idle;
    queued_target_.reset();
  }
}

double Indexer::position(SimTime now) {
  update(now);
  return motion_.position(now);
}

double Indexer::step_rate(SimTime now) {
  update(now);
  return std::abs(motion_.velocity(now));
}

int Indexer::status(SimTime now) {
  update(now);
  int bits = 0;
  const bool moving = motion_.in_motion(now);
  if (moving || home_phase_ != HomePhase::idle) bits |= 1;
  if (moving && motion_.velocity_move() && motion_.acceleration(now) == 0) bits |= 2;
  if (home_phase_ != HomePhase::idle) bits |= 8;
  if (moving && motion_.acceleration(now) != 0) bits |= 32;
  return bits;
}

void Indexer::start_index(SimTime now, double target) {
  const double from = motion_.position(now);
  if ((target > from && limit_plus_) || (target < from && limit_minus_)) return;
  motion_.start_move(now, target, limits(achievable_rate(params_.slew)));
  index_running_ = true;
}

void Indexer::start_home(SimTime now, double speed, int direction) {
  // §6: dir 0 goes - from a low switch and + from a high one; dir 1 the other way round.
  const bool high = home_high(now);
  const double sign = (direction == 0) == high ? 1.0 : -1.0;
  const double edge = home_.edge - origin_;  // in counts
  // Which way the high region lies from here.
  const double toward_high = home_.high_below ? -1.0 : 1.0;
  const MoveLimits seek{std::max(1.0, speed), acceleration(), kInstant};  // no decel at the switch
  home_phase_ = HomePhase::seek;
  if (!high && sign == toward_high) {
    creep_target_ = edge;
    motion_.start_move(now, edge, seek);
  } else if (high && sign == -toward_high) {
    creep_target_ = edge;
    motion_.start_move(now, edge - toward_high, seek);
  } else {
    // Away from the switch: runs until a limit, @ or ESC, as a real axis would.
    motion_.start_velocity(now, sign * speed, acceleration(), deceleration());
  }
}

Indexer::Outcome Indexer::execute(std::string_view line, SimTime now) {
  update(now);
  Outcome out;
  // §1: at most 12 characters; the simulator ignores longer lines (the manual defines no error).
  if (line.empty() || line.size() > 12) return out;
  const char c = line.front();
  const auto parsed = parse_fields(line.substr(1));
  if (!parsed) return out;
  const std::vector<double>& f = *parsed;
  const double f0 = f.empty() ? 0 : f[0];
  const double f1 = f.size() < 2 ? 0 : f[1];
  const auto i0 = static_cast<int>(std::lround(f0));
  const auto i1 = static_cast<int>(std::lround(f1));
  const auto result = [&](std::string text) {
    out.kind = Outcome::Kind::result;
    out.text = std::move(text);
    return out;
  };
  out.kind = Outcome::Kind::completion;
  for (const auto& [letter, parameter] : kEncoderParameters) {
    if (c == letter) {
      params_.*parameter = i0;
      return out;
    }
  }
  switch (c) {
    case 'Z':
      return result(padded(format_position(motion_.position(now))));
    case 'z':
      return result(padded(std::to_string(std::llround(motion_.position(now)))));
    case '^':
      return result(padded(std::to_string(status(now))));
    case ']': {
      if (i0 == 1) return result(padded(std::to_string(home_high(now) ? 1 : 0)));
      return result(padded(std::to_string((limit_plus_ ? 1 : 0) | (limit_minus_ ? 2 : 0))));
    }
    case 'A':
      if (i0 == 129) return result(padded(std::to_string(inputs_ | (outputs_ << 3))));
      outputs_ = (i0 >> 3) & 7;
      return out;
    case '[': {
      const int count = f.size() < 2 ? 1 : std::clamp(i1, 0, 255);
      std::string text;
      for (int k = 0; k < count; ++k) {
        const int address = i0 + k;
        text += (k % 10 == 0 ? "" : " ") +
                std::to_string(address >= 0 && address < 2048 ? nvm_[address] : 0);
        if (k % 10 == 9 || k == count - 1) text += format_.end;
      }
      return result(text.empty() ? format_.end : text);
    }
    case 'B':
      params_.jog_slow = i0;
      params_.jog_fast = i1;
      return out;
    case 'D':
      params_.divide = std::clamp(i0, 0, 8);
      return out;
    case 'E':
      params_.settle = i0;
      return out;
    case 'H':
      params_.resolution = i0 == 1 ? 1 : 0;
      return out;
    case 'I':
      params_.initial_velocity = std::clamp(f0, 20.0, 20000.0);
      return out;
    case 'K':
      params_.accel = std::clamp(i0, 0, 255);
      params_.decel = std::clamp(i1, 0, 255);
      return out;
    case 'T':
      params_.trip_position = f0;
      params_.trip_address = i1;
      return out;
    case 'V':
      params_.slew = std::clamp(f0, 20.0, 20000.0);
      return out;
    case 'Y':
      params_.hold_current = i0;
      params_.run_current = i1;
      return out;
    case 'l':
      params_.limit_mode = std::clamp(i0, 0, 3);
      return out;
    case '+':
    case '-':
    case 'R': {
      if ((c != 'R' && f0 < 0) || std::abs(f0) > kMaxPosition) return {};
      const double base = queued_target_.value_or(motion_.rest_position(now));
      const double target = c == 'R' ? f0 : base + (c == '+' ? f0 : -f0);
      if (index_running_ && motion_.in_motion(now) && !motion_.velocity_move()) {
        // §6: a second action waits for the first; its completion comes when it starts.
        queued_target_ = target;
        queued_start_ = index_end(now).value_or(now);
        out.delay = std::chrono::duration_cast<std::chrono::microseconds>(queued_start_ - now);
        return out;
      }
      start_index(now, target);
      return out;
    }
    case 'M': {
      double v = std::clamp(f0, -20000.0, 20000.0);
      if (v != 0 && std::abs(v) < 20) v = v < 0 ? -20 : 20;
      if ((v > 0 && limit_plus_) || (v < 0 && limit_minus_)) return out;
      index_running_ = false;
      queued_target_.reset();
      motion_.start_velocity(now, v, acceleration(), deceleration());
      return out;
    }
    case 'F':
      start_home(now, std::clamp(f0 == 0 ? 20.0 : f0, 20.0, 20000.0), i1 == 1 ? 1 : 0);
      return out;
    case 'O':
    case 'o':
      // Refused while moving (§3): the line completes, the origin stays.
      if (!motion_.in_motion(now) && home_phase_ == HomePhase::idle) {
        origin_ += motion_.position(now);
        motion_.set_position(now, 0);
      }
      return out;
    case '@':
      soft_stop(now);
      return out;
    case 'S':
      saved_ = params_;
      store_parameters();
      ++eeprom_writes_;
      out.delay = std::chrono::milliseconds(20);
      return out;
    case 'C':
      if (i0 == 0) {
        params_ = saved_;
        return out;
      }
      if (i0 == 8) {
        params_ = saved_ = Parameters{};
        store_parameters();
      }
      ++eeprom_writes_;
      out.delay = std::chrono::milliseconds(200);
      return out;
    case '\\':
      if (i0 >= 0 && i0 < 2048) nvm_[i0] = static_cast<std::uint8_t>(i1);
      ++eeprom_writes_;
      return out;
    case 'W':
      if (i0 == 0) {
        if (const auto end = index_end(now))
          out.delay = std::chrono::duration_cast<std::chrono::microseconds>(*end - now);
      } else {
        out.delay = std::chrono::milliseconds(10) * i0;
      }
      return out;
    case 'X':
      return result("\"32.\r\n");  // what X gives in party mode (§2)
    case 'G':                      // programs are not simulated: accepted, nothing runs
    case 'J':
    case 'j':
    case 'L':
    case 'f':
    case 'k':
    case 'y':
      return out;
    default:
      return {};  // P, Q, q and unknown commands: nothing after the echo
  }
}

void Indexer::hard_stop(SimTime now) {
  update(now);
  motion_.stop(now);
  index_running_ = false;
  queued_target_.reset();
  home_phase_ = HomePhase::idle;
}

void Indexer::soft_stop(SimTime now) {
  update(now);
  motion_.abort(now, deceleration());
  queued_target_.reset();
  home_phase_ = HomePhase::idle;
}

void Indexer::reset(SimTime now) {
  update(now);
  origin_ += motion_.position(now);
  motion_.set_position(now, 0);
  index_running_ = false;
  queued_target_.reset();
  home_phase_ = HomePhase::idle;
  params_ = saved_;
  outputs_ = 0;
}

void Indexer::set_position(SimTime now, double value) {
  update(now);
  motion_.set_position(now, value);
  index_running_ = false;
  queued_target_.reset();
  home_phase_ = HomePhase::idle;
}

std::string Indexer::format_position(double value) const {
  char buffer[32];
  const double hundredths = std::round(value * 100);
  const bool decimals = format_.decimals == ResultFormat::Decimals::always ||
                        (format_.decimals == ResultFormat::Decimals::variable_resolution &&
                         params_.resolution == 1 && std::fmod(hundredths, 100) != 0);
  if (decimals)
    std::snprintf(buffer, sizeof buffer, "%.2f", hundredths / 100);
  else
    std::snprintf(buffer, sizeof buffer, "%lld", std::llround(value));
  return buffer;
}

std::string Indexer::padded(const std::string& number) const {
  switch (format_.padding) {
    case ResultFormat::Padding::right_aligned: {
      char buffer[32];
      std::snprintf(buffer, sizeof buffer, "%7s", number.c_str());
      return buffer + format_.end;
    }
    case ResultFormat::Padding::space:
      return " " + number + format_.end;
    case ResultFormat::Padding::none:
      break;
  }
  return number + format_.end;
}

void Indexer::store_parameters() {
  // The appendix's parameter block at 1984..2019 (digest §5), as `S` leaves it.
  const auto put = [&](int address, int value) {
    nvm_[static_cast<std::size_t>(address)] = static_cast<std::uint8_t>(value & 0xff);
  };
  const auto put_word = [&](int address, std::uint16_t word) {
    put(address, word & 0xff);
    put(address + 1, word >> 8);
  };
  put(1985, saved_.resolution == 1 ? 15 : 14);
  put(1986, saved_.retries);
  put(1987, saved_.divide);
  put(1988, saved_.jog_slow);
  put(1989, saved_.jog_fast);
  put(1990, saved_.accel);
  put(1991, saved_.decel);
  put(1995, saved_.trip_address);
  put(1996, saved_.hold_current);
  put(1997, saved_.run_current);
  put(1998, saved_.settle);
  put_word(1999, static_cast<std::uint16_t>(saved_.encoder_lines));
  put(2001, saved_.stall_factor);
  put_word(2002, static_cast<std::uint16_t>(saved_.deadband));
  put(2004, saved_.stall_interval);
  put_word(2006, velocity_word(saved_.initial_velocity));
  put_word(2011, velocity_word(saved_.slew));
  put_word(2016, velocity_word(saved_.hunt_velocity));
  put(2019, static_cast<unsigned char>(name_));
}

}  // namespace fieldgate::sim::ims
