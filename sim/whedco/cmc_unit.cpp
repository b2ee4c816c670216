#include "sim/whedco/cmc_unit.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace fieldgate::sim::whedco {
namespace {

using namespace std::chrono_literals;

constexpr double kMaxPosition = 8388607;  // 24-bit position register (A.1)
constexpr double kMinPosition = -8388608;
constexpr double kMinVelocity = 10;  // pp/s, trajectory velocity minimum (Table 5-1)
constexpr int kPins = 12;
// A profile that loops without ever waiting must not hang the simulator.
constexpr int kMaxLinesPerAdvance = 10000;

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

SimTime later(SimTime t, double seconds) {
  return t + std::chrono::duration_cast<SimClock::duration>(std::chrono::duration<double>(seconds));
}

std::string_view axis_fault_name(int code) {
  switch (code) {
    case 0:
      return "Power Failure";
    case 2:
      return "Over-temperature";
    case 3:
      return "Excessive Following Error";
    case 4:
      return "Encoder Lost";
    case 5:
      return "Deadband Exceeded";
    case 6:
      return "Lost Enable";
    case 7:
      return "Position Register Overflow";
    case 9:
      return "Over-current";
    case 10:
      return "Motor Stalled";
    default:
      return "Unit Functional";
  }
}

// Length-like parameters the unit ratio scales (§2.3); the rest are stored as entered.
bool scaled_constant(std::string_view mnemonic) {
  return mnemonic == "NO" || mnemonic == "PO";
}

}  // namespace

std::string format_user_value(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.4f", value);
  std::string text = buffer;
  while (text.back() == '0') text.pop_back();
  if (text.back() == '.') text.pop_back();
  if (text == "-0") text = "0";
  return text;
}

CmcUnit::CmcUnit(UnitOptions options, SimTime now) : options_(std::move(options)) {
  if (options_.address < 0 || options_.address > 7)
    throw std::invalid_argument("CMC-0 addresses are 0-7");
  for (const char letter : options_.axes) {
    if (kAxisOrder.find(letter) == std::string_view::npos)
      throw std::invalid_argument(std::string("no axis '") + letter + "' (W, X, Y, Z)");
    Axis& a = axes_[letter];
    a.present = true;
    a.stepper = options_.steppers.find(letter) != std::string::npos;
  }
  runner_time_ = now;
  if (options_.power_failure) power_cycle(now);
}

bool CmcUnit::has_axis(char letter) const {
  return axes_.count(letter) != 0;
}

CmcUnit::Axis* CmcUnit::axis(char letter) {
  const auto it = axes_.find(letter);
  return it == axes_.end() ? nullptr : &it->second;
}

int CmcUnit::axis_fault(char letter) const {
  const auto it = axes_.find(letter);
  return it == axes_.end() ? kAxisFunctional : it->second.fault;
}

std::optional<double> CmcUnit::commanded_position(char letter, SimTime now) {
  Axis* a = axis(letter);
  if (!a) return std::nullopt;
  advance(now);
  update_axes(now);
  return a->motion.position(now);
}

bool CmcUnit::set_analog(int channel, int counts) {
  if (channel < 1 || channel > 4) return false;
  analog_[static_cast<std::size_t>(channel - 1)] = std::clamp(counts, -2047, 2047);
  return true;
}

bool CmcUnit::set_home(char letter, double machine_position) {
  Axis* a = axis(letter);
  if (!a) return false;
  a->home_machine = machine_position;
  return true;
}

void CmcUnit::update_axes(SimTime t) {
  for (auto& [letter, a] : axes_) {
    if (a.homing.searching() && a.homing.update(a.motion, t) == HomingSequence::Phase::succeeded) {
      a.offset = a.home_machine - a.home_set_to;
      a.aux = false;
    }
  }
}

bool CmcUnit::busy(Axis& a, SimTime t) {
  return a.motion.in_motion(t) || a.homing.searching() || a.aux;
}

std::optional<SimTime> CmcUnit::stop_time(Axis& a, SimTime from) {
  if (a.homing.searching() && !a.motion.in_motion(from)) return from;
  if (!a.motion.in_motion(from)) return a.aux ? std::nullopt : std::optional<SimTime>(from);
  if (a.motion.velocity_move()) return std::nullopt;
  double high = 1;
  while (a.motion.in_motion(later(from, high))) {
    high *= 2;
    if (high > 1e7) return std::nullopt;
  }
  double low = 0;
  while (high - low > 1e-6) {
    const double mid = (low + high) / 2;
    (a.motion.in_motion(later(from, mid)) ? low : high) = mid;
  }
  return later(from, high);
}

int CmcUnit::pin_level(int pin) const {
  const int bit = 1 << (pin - 1);
  return ((output_pins_ & bit) ? output_latches_ : input_levels_) & bit ? 1 : 0;
}

double CmcUnit::multiplier_of(const Axis& a) const {
  switch (a.multiplier_source) {
    case 'V':
      return variables_[static_cast<std::size_t>(a.multiplier_index)] / 256.0;
    case 'A':
      return analog_[static_cast<std::size_t>(a.multiplier_index - 1)] / 256.0;
    default:
      return a.multiplier;
  }
}

int CmcUnit::fault_number() const {
  int byte = 0;
  for (std::size_t i = 0; i < kAxisOrder.size(); ++i) {
    const auto it = axes_.find(kAxisOrder[i]);
    if (it != axes_.end() && it->second.fault != kAxisFunctional) byte |= (1 << i) | (1 << (i + 4));
  }
  if (options_.fc_table_codes) {
    const int base = unit_fault_ == UnitFault::functional      ? 8
                     : unit_fault_ == UnitFault::power_failure ? 0
                                                               : static_cast<int>(unit_fault_);
    return base + byte;
  }
  return static_cast<int>(unit_fault_) * 256 + byte;
}

std::string CmcUnit::status_text(int word) const {
  char buffer[24];
  switch (options_.status_format) {
    case StatusFormat::hex:
      std::snprintf(buffer, sizeof buffer, "%04X", word & 0xffff);
      return buffer;
    case StatusFormat::binary: {
      std::string bits;
      for (int b = 15; b >= 0; --b) bits += ((word >> b) & 1) ? '1' : '0';
      return bits;
    }
    case StatusFormat::decimal:
      break;
  }
  return std::to_string(word);
}

std::string CmcUnit::fault_text() const {
  std::string text;
  const auto line = [&](std::string_view l) {
    if (!text.empty()) text += "\r\n";
    text += l;
  };
  switch (unit_fault_) {
    case UnitFault::power_failure:
      line("Power Failure");
      break;
    case UnitFault::axis_initialize:
      line("Axis Initialize");
      break;
    case UnitFault::arithmetic_overflow:
      line("Arithmetic Overflow");
      break;
    case UnitFault::functional:
      break;
  }
  for (const char letter : kAxisOrder) {
    const auto it = axes_.find(letter);
    if (it != axes_.end() && it->second.fault != kAxisFunctional)
      line(std::string(1, letter) + " Faulted");
  }
  if (text.empty()) text = "Unit Functional";
  return text;
}

int CmcUnit::unit_status(SimTime now) {
  advance(now);
  update_axes(now);
  int s = 0;
  for (auto& [letter, a] : axes_)
    if (busy(a, now)) s |= status::busy;
  if (!stack_.empty()) s |= status::busy | status::profile_running;
  const bool axis_faulted = std::any_of(axes_.begin(), axes_.end(), [](const auto& entry) {
    return entry.second.fault != kAxisFunctional;
  });
  if (unit_fault_ != UnitFault::functional || axis_faulted) s |= status::faulted;
  if (defining_) s |= status::defining;
  if (memory_lost_) s |= status::memory_lost;
  return s;
}

int CmcUnit::axis_status(char letter, SimTime now) {
  advance(now);
  update_axes(now);
  Axis* a = axis(letter);
  if (!a) return 0;
  int s = 0;
  if (busy(*a, now)) s |= status::busy;
  if (a->fault != kAxisFunctional) s |= status::faulted;
  if (a->aux) s |= status::aux_enabled;
  if (a->homing.searching()) s |= status::homing;
  if (std::abs(a->motion.position(now) + a->offset - a->home_machine) < 0.5)
    s |= status::home_input;
  return s;
}

void CmcUnit::fault_axis(Axis& a, int code, SimTime t) {
  a.fault = code;
  if (code == kAxisFunctional) return;
  // A faulted axis drops its drive: the motor stops where it is, and so does the profile.
  a.motion.stop(t);
  a.homing.fail();
  a.aux = false;
  stack_.clear();
  wait_ = Wait::none;
}

bool CmcUnit::inject_fault(char letter, int code, SimTime now) {
  Axis* a = axis(letter);
  if (!a || code < 0 || code > 10 || code == 1) return false;
  advance(now);
  update_axes(now);
  fault_axis(*a, code, now);
  return true;
}

void CmcUnit::power_cycle(SimTime now) {
  // Parameters and profiles live in battery-backed RAM (§5.3.1); motion and faults do not.
  for (auto& [letter, a] : axes_) {
    a.motion.set_position(now, 0);
    a.homing.clear();
    a.aux = false;
    a.offset = 0;
    a.fault = 0;
  }
  unit_fault_ = UnitFault::power_failure;
  stack_.clear();
  wait_ = Wait::none;
  defining_.reset();
  runner_time_ = now;
}

void CmcUnit::arithmetic_overflow() {
  unit_fault_ = UnitFault::arithmetic_overflow;
  stack_.clear();
  wait_ = Wait::none;
}

void CmcUnit::halt(SimTime t) {
  for (auto& [letter, a] : axes_) {
    a.homing.fail();
    a.aux = false;
    if (a.motion.in_motion(t)) a.motion.abort(t, a.acceleration);
  }
  // Whether HT also ends a running profile is not in the excerpt; stopping it is the safe
  // reading for a halt (README).
  stack_.clear();
  wait_ = Wait::none;
}

void CmcUnit::reset_parameters() {
  for (auto& [letter, a] : axes_) {
    const bool present = a.present;
    const bool stepper = a.stepper;
    Axis fresh;
    fresh.present = present;
    fresh.stepper = stepper;
    fresh.motion = a.motion;
    a = fresh;
  }
  parameters_.clear();
  variables_.fill(0);
  booleans_.fill(false);
  output_latches_ = 0;
  output_pins_ = 0;
}

double CmcUnit::user_to_internal(const Value& v, const Axis* scale_axis,
                                 double per_variable) const {
  if (v.kind == Value::Kind::variable)
    return variables_[static_cast<std::size_t>(v.variable)] / per_variable;
  return std::round(v.number * (scale_axis ? scale_axis->unit_ratio : 1));
}

std::optional<std::int64_t> CmcUnit::evaluate(std::string_view rhs, SimTime t, bool& overflow) {
  overflow = false;
  std::size_t i = 0;
  const auto operand = [&]() -> std::optional<std::int64_t> {
    const auto eat = [&](std::string_view s) {
      if (rhs.substr(i).starts_with(s)) {
        i += s.size();
        return true;
      }
      return false;
    };
    if (eat("PHE") || eat("PHP")) return 0;  // no PLL master is simulated
    if (eat("P")) {
      Axis* a = axis(rhs[i++]);
      if (!a) return std::nullopt;
      return static_cast<std::int64_t>(std::llround(a->motion.position(t)));
    }
    bool invert = eat("N");
    const char kind = rhs[i++];
    const int d = hex_value(rhs[i++]);
    switch (kind) {
      case 'B':
        return booleans_[static_cast<std::size_t>(d)] != invert ? 1 : 0;
      case 'I':
        return d >= 1 && d <= kPins ? (pin_level(d) != 0) != invert : 0;
      case 'V':
        return variables_[static_cast<std::size_t>(d)];
      case 'A':
        return d >= 1 && d <= 4 ? analog_[static_cast<std::size_t>(d - 1)] : 0;
      default:  // E (encoder change), T (thumbwheel digit): nothing is connected
        return 0;
    }
  };
  if (rhs.empty()) return std::nullopt;
  if (rhs[0] == '-' || rhs[0] == '+' || (rhs[0] >= '0' && rhs[0] <= '9'))
    return std::stoll(std::string(rhs));
  const auto a = operand();
  if (!a) return std::nullopt;
  if (i >= rhs.size()) return a;
  const char op = rhs[i++];
  const auto b = operand();
  if (!b) return std::nullopt;
  std::int64_t result = 0;
  switch (op) {
    case '*':
      result = *a * *b;
      break;
    case '/':
      if (*b == 0) {
        overflow = true;
        return std::nullopt;
      }
      result = *a / *b;
      break;
    case '+':
      result = *a + *b;
      break;
    default:
      result = *a - *b;
      break;
  }
  if (result > std::numeric_limits<std::int32_t>::max() ||
      result < std::numeric_limits<std::int32_t>::min()) {
    overflow = true;
    return std::nullopt;
  }
  return result;
}

bool CmcUnit::condition_true(std::string_view text, SimTime t) {
  if (text.starts_with("V")) {
    const std::int32_t a = variables_[static_cast<std::size_t>(hex_value(text[1]))];
    const std::int32_t b = variables_[static_cast<std::size_t>(hex_value(text.back()))];
    const std::string_view op = text.substr(2, text.size() - 4);
    if (op == ">") return a > b;
    if (op == "<") return a < b;
    if (op == "<>") return a != b;
    return a == b;
  }
  std::size_t i = 0;
  const auto term = [&]() {
    bool invert = false;
    if (text[i] == 'N') {
      invert = true;
      ++i;
    }
    const char kind = text[i++];
    const int d = hex_value(text[i++]);
    const bool level =
        kind == 'B' ? booleans_[static_cast<std::size_t>(d)] : (d >= 1 && pin_level(d) != 0);
    return level != invert;
  };
  const bool first = term();
  if (i >= text.size()) return first;
  const char op = text[i++];
  const bool second = term();
  (void)t;
  if (op == 'A') return first && second;
  if (op == 'O') return first || second;
  return first != second;
}

void CmcUnit::start_profile(int number, SimTime t) {
  stack_.assign(1, Frame{number, 0, 0});
  wait_ = Wait::none;
  runner_time_ = t;
}

bool CmcUnit::start_run(const Command& c, SimTime t) {
  std::string letters = c.axes;
  if (c.op == Op::run_radius || c.op == Op::run_circle) {
    // Arcs and circles are not traced; an arc runs as the straight incremental move to its end
    // point (what the manual says happens beyond 120°), a full circle ends where it started.
    if (c.op == Op::run_circle) return true;
    letters = c.axes == "X" ? "XY" : (c.axes == "W" ? "WZ" : "XYWZ");
  }
  struct Leg {
    Axis* axis;
    double target;
    double distance;
  };
  std::vector<Leg> legs;
  for (const char letter : letters) {
    Axis* a = axis(letter);
    if (!a) return false;
    if (a->fault != kAxisFunctional) continue;  // a faulted axis does not move
    const double from = a->motion.position(t);
    const double target = c.op == Op::run_absolute
                              ? a->absolute_move
                              : a->motion.rest_position(t) + a->incremental_move;
    if ((target > kMaxPosition || target < kMinPosition) && a->constants["WR"] == 0) {
      fault_axis(*a, 7, t);  // Position Register Overflow
      return true;
    }
    legs.push_back({a, target, target - from});
  }
  const Leg* lead = nullptr;
  for (const Leg& l : legs)
    if (!lead || std::abs(l.distance) > std::abs(lead->distance)) lead = &l;
  if (!lead || std::abs(lead->distance) < 1e-9) return true;
  // Linear interpolation: every axis runs the lead axis' profile scaled by its share of the
  // distance, so all arrive together. The lead axis runs at its pair's velocity (VX for X/Y,
  // VW for W/Z) and its own acceleration.
  const char lead_letter = [&] {
    for (const auto& [letter, a] : axes_)
      if (&a == lead->axis) return letter;
    return 'X';
  }();
  const bool xy_pair = lead_letter == 'X' || lead_letter == 'Y';
  const auto pv = parameters_.find(xy_pair ? "VX" : "VW");
  const double velocity = std::max(kMinVelocity, pv == parameters_.end() ? 0.0 : pv->second);
  const double acceleration = lead->axis->acceleration;
  for (const Leg& l : legs) {
    const double share = std::abs(l.distance) / std::abs(lead->distance);
    if (share < 1e-12) continue;
    l.axis->aux = false;
    l.axis->motion.start_move(t, l.target,
                              {velocity * share, acceleration * share, acceleration * share});
  }
  return true;
}

std::string CmcUnit::query(const Command& c) {
  Axis* a = c.axis ? axis(c.axis) : nullptr;
  if (c.axis && !a && c.op != Op::load) return "?";
  switch (c.op) {
    case Op::unit_ratio:
      return std::to_string(a->unit_ratio);
    case Op::axis_constant: {
      const double v = a->constants[c.mnemonic];
      return format_user_value(scaled_constant(c.mnemonic) ? v / a->unit_ratio : v);
    }
    case Op::multiplier:
      return format_user_value(multiplier_of(*a));
    case Op::load: {
      const bool per_axis = c.mnemonic == "AM" || c.mnemonic == "IM" || c.mnemonic == "AC" ||
                            c.mnemonic == "FS" || c.mnemonic == "EL" || c.mnemonic == "SN";
      if (per_axis && !a) return "?";
      if (c.mnemonic == "SN") return "0";
      if (c.mnemonic == "AM") return format_user_value(a->absolute_move / a->unit_ratio);
      if (c.mnemonic == "IM") return format_user_value(a->incremental_move / a->unit_ratio);
      if (c.mnemonic == "AC") return format_user_value(a->acceleration / a->unit_ratio);
      if (c.mnemonic == "FS") return format_user_value(a->frequency / a->unit_ratio);
      if (c.mnemonic == "EL") return format_user_value(a->ellipse);
      Axis* pair_axis = axis(c.axis);
      const double ratio = pair_axis ? pair_axis->unit_ratio : 1;
      std::string key = c.mnemonic;
      if (c.mnemonic == "AD" || c.mnemonic == "AO") key += std::to_string(c.index);
      const double v = parameters_.count(key) ? parameters_[key] : 0.0;
      const bool scaled =
          c.mnemonic == "VX" || c.mnemonic == "VW" || c.mnemonic == "RX" || c.mnemonic == "RW";
      return format_user_value(scaled ? v / ratio : v);
    }
    default:
      return "?";
  }
}

std::string CmcUnit::run(const Command& c, SimTime t, bool from_profile) {
  if (c.query()) return query(c);
  Axis* a = c.axis ? axis(c.axis) : nullptr;
  const bool axis_command =
      c.axis && c.op != Op::load && c.op != Op::radius_increment && c.op != Op::wait_motion;
  if (axis_command && !a) return "?";
  switch (c.op) {
    case Op::warm_boot:
      unit_fault_ = UnitFault::functional;
      memory_lost_ = false;
      for (auto& [letter, x] : axes_) x.fault = kAxisFunctional;
      return {};
    case Op::cold_boot:
      halt(t);
      reset_parameters();
      profiles_.clear();
      memory_lost_ = true;
      return {};
    case Op::memory_transfer:
      return "?";
    case Op::parallel_enable:
      parameters_["PE"] = c.flag;
      return {};
    case Op::diagnostics:
      parameters_["DG"] = c.flag;
      return {};
    case Op::profile128_enable:
      parameters_["UE"] = c.flag;
      return {};
    case Op::empty_buffer:
    case Op::set_point:
    case Op::teach_point:
    case Op::pll_zero_counter:
    case Op::wait_index:
      return {};
    case Op::initialize:
      // §6.1.2: ITa always faults the CMC-0 ("Axis Initialize"); WB clears it.
      a->motion.stop(t);
      unit_fault_ = UnitFault::axis_initialize;
      return {};
    case Op::unit_ratio: {
      const double v = c.value.number;
      if (v != std::floor(v) || v < 1 || v > 10000) return "?";
      a->unit_ratio = static_cast<int>(v);
      return {};
    }
    case Op::axis_constant:
      a->constants[c.mnemonic] =
          scaled_constant(c.mnemonic) ? std::round(c.value.number * a->unit_ratio) : c.value.number;
      return {};
    case Op::define:
    case Op::teach_start:
      if (from_profile) return "?";
      defining_ = c.index;
      edit_line_ = 0;
      if (const auto it = profiles_.find(c.index); it != profiles_.end() && !it->second.empty())
        return it->second.front();  // §5.17: an existing profile opens in edit mode
      return options_.de_answers_ed && c.op == Op::define ? "ED" : std::string{};
    case Op::end_definition:
    case Op::edit_next:
    case Op::edit_delete:
      return "?";  // only inside a definition
    case Op::repeat: {
      if (!from_profile || stack_.empty()) return {};
      Frame& f = stack_.back();
      if (c.index == 0 || f.repeats < c.index) {
        ++f.repeats;
        f.line = 0;
      }
      return {};
    }
    case Op::goto_profile:
    case Op::gosub: {
      const auto it = profiles_.find(c.index);
      if (it == profiles_.end() || it->second.empty()) return from_profile ? std::string{} : "?";
      if (from_profile && c.op == Op::gosub)
        stack_.push_back({c.index, 0, 0});
      else
        start_profile(c.index, t);
      return {};
    }
    case Op::if_branch: {
      if (!condition_true(c.text, t)) return {};
      Command branch = c;
      branch.op = c.gosub ? Op::gosub : Op::goto_profile;
      return run(branch, t, from_profile);
    }
    case Op::halt:
      halt(t);
      return {};
    case Op::set_position: {
      // §5.5: ignored unless the axis is stopped.
      if (busy(*a, t) || a->fault != kAxisFunctional) return {};
      const double position =
          c.value.kind == Value::Kind::number ? std::round(c.value.number * a->unit_ratio) : 0.0;
      if (c.letter == 'T') {
        a->offset += a->motion.position(t) - position;
        a->motion.set_position(t, position);
        return {};
      }
      // Home, index or both: searched with the auxiliary equation at FS x LM. The simulated
      // home input and index pulse sit at the same machine position.
      const double speed = std::abs(a->frequency * multiplier_of(*a));
      a->aux = true;
      a->home_set_to = position;
      if (speed <= 0) return {};  // no search speed: the search never gets anywhere
      a->homing.start(a->motion, t, a->home_machine - a->offset,
                      {speed, a->acceleration, a->acceleration}, position);
      return {};
    }
    case Op::load: {
      Axis* scale = c.axis ? axis(c.axis) : nullptr;
      if (c.mnemonic == "AM" || c.mnemonic == "IM" || c.mnemonic == "AC" || c.mnemonic == "FS" ||
          c.mnemonic == "EL" || c.mnemonic == "SN") {
        if (!a) return "?";
        const double v = user_to_internal(c.value, a, c.mnemonic == "EL" ? 65535.0 : 1.0);
        if (c.mnemonic == "AM") {
          if (v > kMaxPosition || v < -kMaxPosition) return "?";
          a->absolute_move = v;
        } else if (c.mnemonic == "IM") {
          if (std::abs(v) > 65535) return "?";
          a->incremental_move = v;
        } else if (c.mnemonic == "AC") {
          if (v < 80000 || v > 6500000) return "?";
          a->acceleration = v;
        } else if (c.mnemonic == "FS") {
          if (v != 0 && (v < 200 || v > 51200)) return "?";
          a->frequency = v;
        } else if (c.mnemonic == "EL") {
          a->ellipse = c.value.kind == Value::Kind::variable ? v : c.value.number;
        }
        return {};
      }
      const bool scaled =
          c.mnemonic == "VX" || c.mnemonic == "VW" || c.mnemonic == "RX" || c.mnemonic == "RW";
      double v = scaled ? user_to_internal(c.value, scale) : user_to_internal(c.value, nullptr);
      if (c.value.kind == Value::Kind::number && !scaled) v = c.value.number;
      if ((c.mnemonic == "VX" || c.mnemonic == "VW") && (v < kMinVelocity || v > 655350))
        return "?";
      std::string key = c.mnemonic;
      if (c.mnemonic == "AD" || c.mnemonic == "AO") key += std::to_string(c.index);
      parameters_[key] = v;
      return {};
    }
    case Op::radius_increment: {
      Axis* scale = axis(c.axis);
      const std::string key = c.axis == 'X' ? "RX" : "RW";
      parameters_[key] += user_to_internal(c.value, scale);
      return {};
    }
    case Op::run_absolute:
    case Op::run_incremental:
    case Op::run_radius:
    case Op::run_circle:
      return start_run(c, t) ? std::string{} : "?";
    case Op::wait_time:
      if (from_profile) {
        wait_ = Wait::time;
        wait_until_ = later(t, c.value.number);
      }
      return {};
    case Op::wait_motion:
      if (c.axis != 'A' && !axis(c.axis)) return "?";
      if (from_profile) {
        wait_ = Wait::motion;
        wait_axis_ = c.axis;
      }
      return {};
    case Op::wait_condition:
      if (from_profile) {
        wait_ = Wait::condition;
        wait_condition_ = c.text;
      }
      return {};
    case Op::aux_enable:
      if (a->fault != kAxisFunctional) return {};
      a->homing.fail();
      if (c.flag) {
        a->aux = true;
        const double source = a->input_source == 'F' ? a->frequency : 0.0;
        const double velocity = source * multiplier_of(*a);
        if (velocity != 0) a->motion.start_velocity(t, velocity, a->acceleration, a->acceleration);
      } else {
        a->aux = false;
        if (a->motion.in_motion(t)) a->motion.abort(t, a->acceleration);
      }
      return {};
    case Op::multiplier:
      a->multiplier_source = c.letter;
      a->multiplier = c.value.number;
      a->multiplier_index = c.index;
      return {};
    case Op::input_source:
      a->input_source = c.letter;
      return {};
    case Op::set_bit:
    case Op::reset_bit: {
      const bool on = c.op == Op::set_bit;
      if (c.letter == 'B') {
        booleans_[static_cast<std::size_t>(c.index)] = on;
      } else {
        if (c.index < 1 || c.index > kPins) return "?";
        const int bit = 1 << (c.index - 1);
        output_latches_ = on ? (output_latches_ | bit) : (output_latches_ & ~bit);
      }
      return {};
    }
    case Op::direction: {
      const int bit = 1 << (c.index - 1);
      output_pins_ = c.flag ? (output_pins_ & ~bit) : (output_pins_ | bit);  // 1 = input
      return {};
    }
    case Op::report_analog:
      if (c.index < 1 || c.index > 4) return "?";
      return std::to_string(analog_[static_cast<std::size_t>(c.index - 1)]);
    case Op::report_booleans: {
      int mask = 0;
      for (std::size_t i = 0; i < booleans_.size(); ++i)
        if (booleans_[i]) mask |= 1 << i;
      return std::to_string(mask);
    }
    case Op::report_inputs: {
      int mask = 0;
      for (int pin = 1; pin <= kPins; ++pin)
        if (pin_level(pin)) mask |= 1 << (pin - 1);
      return std::to_string(mask);
    }
    case Op::variable_query:
      return std::to_string(variables_[static_cast<std::size_t>(c.index)]);
    case Op::variable_assign: {
      bool overflow = false;
      const auto v = evaluate(c.text, t, overflow);
      if (overflow) {
        arithmetic_overflow();
        return {};
      }
      if (!v) return "?";
      variables_[static_cast<std::size_t>(c.index)] = static_cast<std::int32_t>(*v);
      return {};
    }
    case Op::unit_status:
      return status_text(unit_status(t));
    case Op::axis_status:
      return status_text(axis_status(c.axis, t));
    case Op::command_position:
      return format_user_value(a->motion.position(t) / a->unit_ratio);
    case Op::actual_position:
    case Op::following_error: {
      const SimTime lagged = a->stepper ? t : t - options_.servo_lag;
      const double actual = std::round(a->motion.position(lagged));
      if (c.op == Op::actual_position) return format_user_value(actual / a->unit_ratio);
      return format_user_value((std::round(a->motion.position(t)) - actual) / a->unit_ratio);
    }
    case Op::unit_fault:
      return options_.echo ? fault_text() : std::to_string(fault_number());
    case Op::axis_fault: {
      if (options_.echo) return std::string(axis_fault_name(a->fault));
      const char digits[] = "0123456789A";
      return std::string(1, digits[a->fault]);
    }
  }
  return "?";
}

std::string CmcUnit::definition_line(std::string_view body) {
  auto& lines = profiles_[*defining_];
  if (body == "ED") {
    defining_.reset();
    return {};
  }
  if (body == "X") {
    if (edit_line_ < lines.size()) ++edit_line_;
    return edit_line_ < lines.size() ? lines[edit_line_] : "ED";
  }
  if (body == "DEL") {
    if (edit_line_ < lines.size()) lines.erase(lines.begin() + static_cast<long>(edit_line_));
    return {};
  }
  const auto c = parse_command(body);
  if (!c || !allowed_in_profile(*c)) return "?";
  // §5.17: a statement typed in edit mode goes in front of the current line.
  lines.insert(lines.begin() + static_cast<long>(edit_line_), std::string(body));
  ++edit_line_;
  return {};
}

bool CmcUnit::define_profile(int number, const std::vector<std::string>& lines,
                             std::string& error) {
  if (number < 0 || number > 255) {
    error = "profile numbers are 0-255";
    return false;
  }
  for (const auto& l : lines) {
    const auto c = parse_command(l);
    if (!c || !allowed_in_profile(*c)) {
      error = "not a profile statement: '" + l + "'";
      return false;
    }
  }
  profiles_[number] = lines;
  return true;
}

void CmcUnit::advance(SimTime now) {
  int budget = kMaxLinesPerAdvance;
  while (!stack_.empty() && budget-- > 0) {
    SimTime t = runner_time_;
    switch (wait_) {
      case Wait::none:
        break;
      case Wait::time:
        if (wait_until_ > now) return;
        t = wait_until_;
        break;
      case Wait::motion: {
        std::optional<SimTime> done = t;
        for (auto& [letter, a] : axes_) {
          if (wait_axis_ != 'A' && letter != wait_axis_) continue;
          const auto stop = stop_time(a, t);
          if (!stop) {
            done.reset();
            break;
          }
          done = std::max(*done, *stop);
        }
        if (!done || *done > now) return;
        t = *done;
        break;
      }
      case Wait::condition:
        if (!condition_true(wait_condition_, now)) return;
        t = std::max(t, now);
        break;
    }
    wait_ = Wait::none;
    runner_time_ = t;
    update_axes(t);
    Frame& f = stack_.back();
    const auto it = profiles_.find(f.profile);
    if (it == profiles_.end() || f.line >= it->second.size()) {
      stack_.pop_back();  // end of a GOSUB returns; end of the top profile stops
      continue;
    }
    const std::string line = it->second[f.line++];
    const auto c = parse_command(line);
    if (!c) continue;
    // A run command waits for the axes it moves; moves are not blended in this simulator.
    if (c->op == Op::run_absolute || c->op == Op::run_incremental || c->op == Op::run_radius) {
      bool moving = false;
      for (auto& [letter, a] : axes_)
        if (a.motion.in_motion(t)) moving = true;
      if (moving) {
        --f.line;
        wait_ = Wait::motion;
        wait_axis_ = 'A';
        continue;
      }
    }
    run(*c, t, true);
  }
}

std::string CmcUnit::execute(std::string_view body, SimTime now) {
  advance(now);
  update_axes(now);
  if (runner_time_ < now && stack_.empty()) runner_time_ = now;
  if (!body.empty() && body.front() == '!') {
    defining_.reset();  // §5.17: "!" right after the address leaves edit mode
    return {};
  }
  if (body.find('!') != std::string_view::npos) return {};  // the whole line is ignored
  if (defining_) return definition_line(body);
  const auto c = parse_command(body);
  if (!c) return "?";
  std::string reply = run(*c, now, false);
  // A profile started interactively runs up to its first wait right away.
  advance(now);
  return reply;
}

}  // namespace fieldgate::sim::whedco
