#include "sim/centent/cn0170_unit.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <utility>

namespace fieldgate::sim::centent {

namespace {

constexpr double kRawPerStep = 1024.0;
constexpr double kVelocityEpsilon = 1e-6;

struct Number {
  double value = 0;  // decimal value as written, or the raw value of a hex number
  bool hex = false;
};

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

// "1000", "3333.3", ".1", or hex "0FA000H" (must start with a digit, p.2).
std::optional<Number> parse_number(std::string_view s) {
  if (s.empty()) return std::nullopt;
  if (s.back() == 'H') {
    s.remove_suffix(1);
    if (s.empty() || s.size() > 9 || !is_digit(s.front())) return std::nullopt;
    std::uint64_t raw = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), raw, 16);
    if (ec != std::errc{} || p != s.data() + s.size() || raw > 0xffffffffu) return std::nullopt;
    return Number{static_cast<double>(raw), true};
  }
  bool digits = false, point = false;
  for (char c : s) {
    if (is_digit(c)) {
      digits = true;
    } else if (c == '.' && !point) {
      point = true;
    } else {
      return std::nullopt;
    }
  }
  if (!digits) return std::nullopt;
  return Number{std::strtod(std::string(s).c_str(), nullptr), false};
}

std::optional<int> parse_small(std::string_view s, int lo, int hi) {
  int v = 0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc{} || p != s.data() + s.size() || v < lo || v > hi)
    return std::nullopt;
  return v;
}

// Hex as the CN0170 prints it: fixed width, a 0 in front when the first digit is a letter.
std::string hex_field(std::uint64_t value, int width) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%0*llX", width, static_cast<unsigned long long>(value));
  std::string s(buf);
  if (!is_digit(s.front())) s.insert(s.begin(), '0');
  return s;
}

// Velocities are stored to .25 steps/s (p.28).
std::optional<double> velocity_of(std::string_view text, double lo) {
  const auto n = parse_number(text);
  if (!n) return std::nullopt;
  const double v = n->hex ? n->value / 4.0 : std::round(n->value * 4.0) / 4.0;
  if (v < lo || v > 16383.75) return std::nullopt;
  return v;
}

// "base,max" of V= and XYV= (p.28): either may be left out, not both; nullopt if malformed.
struct VelocityPair {
  std::optional<double> base, max;
};
std::optional<VelocityPair> velocity_pair_of(std::string_view text) {
  const auto comma = text.find(',');
  const auto base = text.substr(0, comma);
  const auto max = comma == std::string_view::npos ? std::string_view{} : text.substr(comma + 1);
  VelocityPair pair;
  if (!base.empty() && !(pair.base = velocity_of(base, 0))) return std::nullopt;
  if (!max.empty() && !(pair.max = velocity_of(max, 0.25))) return std::nullopt;
  if (!pair.base && !pair.max) return std::nullopt;
  return pair;
}

SimTime end_of_motion(const MotionAxis& m, SimTime from) {
  if (!m.in_motion(from)) return from;
  if (m.velocity_move()) return SimTime::max();
  auto span = std::chrono::nanoseconds(std::chrono::milliseconds(1));
  while (m.in_motion(from + span)) {
    span *= 2;
    if (span > std::chrono::hours(1000)) return from + span;
  }
  auto lo = span / 2, hi = span;
  while (hi - lo > std::chrono::nanoseconds(1000)) {
    const auto mid = lo + (hi - lo) / 2;
    (m.in_motion(from + mid) ? lo : hi) = mid;
  }
  return from + hi;
}

std::uint32_t wrap32(double raw) {
  return static_cast<std::uint32_t>(static_cast<std::int64_t>(std::llround(raw)));
}

}  // namespace

Cn0170Unit::Cn0170Unit(int number, const UnitSettings& settings, SimTime now)
    : number_(number), settings_(settings), clock_set_at_(now) {
  for (Axis* a : {&x_, &y_}) {
    a->home_switch = -settings_.home_distance_steps * kRawPerStep;
    a->busy_until = now;
  }
}

std::uint32_t Cn0170Unit::position_register(char letter, SimTime now) const {
  return wrap32(axis(letter).motion.position(now));
}

bool Cn0170Unit::moving(char letter, SimTime now) const {
  return std::abs(axis(letter).motion.velocity(now)) > kVelocityEpsilon;
}

MoveLimits Cn0170Unit::limits(const Axis& a) const {
  const double acc = std::max(1, a.acceleration) * 64.0 * kRawPerStep;
  return {std::max(0.25, a.max_velocity) * kRawPerStep, acc, acc};
}

void Cn0170Unit::start_move(Axis& a, SimTime at, double target, double velocity,
                            double acceleration) {
  const double from = a.motion.position(at);
  a.motion.start_move(at, target, {velocity, acceleration, acceleration});
  a.endless = false;
  a.busy_until = end_of_motion(a.motion, at);
  a.move_pending = true;
  a.vmax_at.reset();
  if (std::abs(target - from) * acceleration >= velocity * velocity)
    a.vmax_at = at + std::chrono::duration_cast<SimClock::duration>(
                         std::chrono::duration<double>(velocity / acceleration));
}

void Cn0170Unit::start_speed(Axis& a, SimTime at, double velocity) {
  const double acc = limits(a).acceleration;
  a.motion.start_velocity(at, velocity, acc, acc);
  a.endless = true;
  a.busy_until = at;
  a.move_pending = false;
  a.vmax_at.reset();
  if (std::abs(velocity) > 0)
    a.vmax_at = at + std::chrono::duration_cast<SimClock::duration>(
                         std::chrono::duration<double>(std::abs(velocity) / acc));
}

void Cn0170Unit::queue_motion(unsigned axes, SimTime now, std::function<void(SimTime)> start) {
  if (queue_.size() >= settings_.staging + settings_.immediate_queue) {
    ++counters_.lost;  // "overwritten or corrupted" (p.6)
    return;
  }
  queue_.push_back({axes, now, std::move(start)});
}

void Cn0170Unit::finish_moves(SimTime t, std::vector<std::string>& events) {
  for (Axis* a : {&x_, &y_}) {
    if (a->homing.searching() && !a->motion.in_motion(t) &&
        a->homing.update(a->motion, t) == HomingSequence::Phase::succeeded)
      a->home_switch = 0;
    if (a->vmax_at && *a->vmax_at <= t) {
      if (a->velocity_trigger) events.push_back(std::string(1, a->letter) + "V");
      a->vmax_at.reset();
    }
    if (a->move_pending && !a->endless && a->busy_until <= t) {
      a->move_pending = false;
      if (a->position_trigger) events.push_back(std::string(1, a->letter) + "P");
    }
  }
}

void Cn0170Unit::advance(SimTime now, std::vector<std::string>& events) {
  for (;;) {
    bool started = false;
    unsigned blocked = 0;
    for (auto it = queue_.begin(); it != queue_.end(); ++it) {
      if (it->axes & blocked) {
        blocked |= it->axes;
        continue;
      }
      SimTime ready = it->queued_at;
      if (it->axes & 1) ready = std::max(ready, x_.busy_until);
      if (it->axes & 2) ready = std::max(ready, y_.busy_until);
      if (ready <= now) {
        finish_moves(ready, events);
        auto start = std::move(it->start);
        queue_.erase(it);
        start(ready);
        started = true;
        break;
      }
      blocked |= it->axes;
    }
    if (!started) break;
  }
  finish_moves(now, events);
  if (!rts_overflow_) {
    if (!warned_ && queue_.size() + 2 >= settings_.staging + settings_.immediate_queue) {
      events.push_back("Q*");
      warned_ = true;
    } else if (warned_ && queue_.size() <= settings_.staging) {
      events.push_back("*Q");
      warned_ = false;
    }
  }
}

void Cn0170Unit::quit(SimTime now) {
  queue_.clear();
  for (Axis* a : {&x_, &y_}) {
    if (a->homing.searching()) a->homing.fail();
    const bool was_moving = a->motion.in_motion(now);
    if (was_moving) a->motion.abort(now, limits(*a).deceleration);
    a->endless = false;
    a->busy_until = end_of_motion(a->motion, now);
    a->move_pending = was_moving;
    a->vmax_at.reset();
  }
}

void Cn0170Unit::kill(SimTime now) {
  ++counters_.kills;
  queue_.clear();
  for (Axis* a : {&x_, &y_}) {
    if (a->homing.searching()) a->homing.fail();
    a->motion.stop(now);
    a->endless = false;
    a->busy_until = now;
    a->move_pending = false;
    a->vmax_at.reset();
    a->joystick = 0;
  }
  warned_ = false;
}

void Cn0170Unit::power_up(SimTime now) {
  kill(now);
  --counters_.kills;
  for (Axis* a : {&x_, &y_}) {
    const double p = a->motion.position(now);
    a->motion.set_position(now, 0);
    a->home_switch -= p;
  }
  outputs_ = {};
  aux_outputs_ = 0;
  clock_set_at_ = now;
  clock_seconds_ = 0;
  month_ = 1;
  day_ = 1;
  year_ = 0;
}

void Cn0170Unit::set_analog(char channel, int value, SimTime now) {
  const std::size_t i = channel == 'X' ? 0 : channel == 'Y' ? 1 : channel == '1' ? 2 : 3;
  analog_[i] = std::clamp(value, 0, 255);
  if (i > 1) return;
  Axis& a = i == 0 ? x_ : y_;
  if (a.joystick == 0) return;
  // Half scale is the centre; modes 2, 5, 7 have a 12 % dead band, 3 a 25 % one; 4–7 are
  // logarithmic (approximated by a square law).
  const double frac = std::clamp((analog_[i] - 128) / 127.0, -1.0, 1.0);
  double band = 0;
  if (a.joystick == 2 || a.joystick == 5 || a.joystick == 7) band = 0.12;
  if (a.joystick == 3) band = 0.25;
  double magnitude = std::abs(frac) <= band ? 0.0 : (std::abs(frac) - band) / (1.0 - band);
  if (a.joystick >= 4) magnitude *= magnitude;
  start_speed(a, now, std::copysign(magnitude * a.max_velocity * kRawPerStep, frac));
}

std::string Cn0170Unit::time_of_day(SimTime now) const {
  const auto elapsed =
      std::chrono::duration_cast<std::chrono::seconds>(now - clock_set_at_).count();
  const long s = (clock_seconds_ + elapsed) % 86400;
  char buf[16];
  std::snprintf(buf, sizeof buf, "%02ld:%02ld.%02ld", s / 3600, s / 60 % 60, s % 60);
  return buf;
}

std::string Cn0170Unit::date() const {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%02d/%02d/%02d", month_, day_, year_);
  return buf;
}

namespace {

// The hex suffix must be an upper-case H (p.2, 38); letters are otherwise case-insensitive.
bool lower_case_hex_suffix(std::string_view s) {
  for (std::size_t i = 1; i < s.size(); ++i)
    if (s[i] == 'h' && std::isxdigit(static_cast<unsigned char>(s[i - 1])) &&
        (i + 1 == s.size() || std::string_view(",&^ ").find(s[i + 1]) != std::string_view::npos))
      return true;
  return false;
}

}  // namespace

bool Cn0170Unit::execute(std::string_view instruction, SimTime now,
                         std::vector<std::string>& replies) {
  if (lower_case_hex_suffix(instruction)) {
    ++counters_.instructions;
    ++counters_.rejects;
    replies.push_back("\"" + std::string(instruction) + "\" ?");
    return false;
  }
  std::string s;
  for (char c : instruction)
    if (c != ' ' && c != '\t') s += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (s.empty()) return false;
  ++counters_.instructions;
  if (s == "K" && mode_ != 2) {
    kill(now);
    return true;
  }
  if (!run(s, now, replies)) {
    ++counters_.rejects;
    replies.push_back("\"" + std::string(instruction) + "\" ?");
  }
  return false;
}

bool Cn0170Unit::run(const std::string& s, SimTime now, std::vector<std::string>& replies) {
  if (s == "M?") {
    ++counters_.queries;
    replies.push_back("M" + std::to_string(mode_));
    return true;
  }
  if (s == "M1" || s == "M3") {
    mode_ = s[1] - '0';
    return true;
  }
  if (s == "M2") {
    if (mode_ == 1) program_.clear();  // from M1 a new download; from M3 an append (p.7)
    mode_ = 2;
    return true;
  }
  if (mode_ == 2) {
    program_.push_back(s);
    return true;
  }
  if (s == "M1\\+" || s == "M1\\-") {
    if (!settings_.accept_backslash_overflow) return false;
    rts_overflow_ = s.back() == '+';
    return true;
  }
  if (s == "M1+" || s == "M1-") {
    if (!settings_.accept_plain_overflow) return false;
    rts_overflow_ = s.back() == '+';
    return true;
  }
  if (s.back() == '?') return query(s, now, replies);
  if (s == "Q") {
    quit(now);
    return true;
  }
  if (s == "G" || s == "H") return true;  // programs are stored, not run, by the simulator
  if (s[0] == 'G') return parse_small(std::string_view(s).substr(1), 1, 65535).has_value();
  if (s == "P1\\G" || s == "P1\\I") {
    in1_is_go_ = s.back() == 'G';
    return true;
  }
  if (s.rfind("T=", 0) == 0) {
    // hh:mm[.ss]
    const std::string_view t = std::string_view(s).substr(2);
    if (t.size() != 5 && t.size() != 8) return false;
    const auto h = parse_small(t.substr(0, 2), 0, 23);
    const auto m = parse_small(t.substr(3, 2), 0, 59);
    const auto sec = t.size() == 8 ? parse_small(t.substr(6, 2), 0, 59) : std::optional<int>(0);
    if (t[2] != ':' || (t.size() == 8 && t[5] != '.') || !h || !m || !sec) return false;
    clock_seconds_ = *h * 3600 + *m * 60 + *sec;
    clock_set_at_ = now;
    return true;
  }
  if (s.rfind("D=", 0) == 0) {
    const std::string_view d = std::string_view(s).substr(2);
    if (d.size() != 8 || d[2] != '/' || d[5] != '/') return false;
    const auto mo = parse_small(d.substr(0, 2), 1, 12);
    const auto da = parse_small(d.substr(3, 2), 1, 31);
    const auto yy = parse_small(d.substr(6, 2), 0, 99);
    if (!mo || !da || !yy) return false;
    month_ = *mo;
    day_ = *da;
    year_ = *yy;
    return true;
  }
  if (s.rfind("XYV=", 0) == 0) {
    const auto pair = velocity_pair_of(std::string_view(s).substr(4));
    if (!pair) return false;
    if (pair->base) vector_base_ = *pair->base;
    if (pair->max) vector_max_ = *pair->max;
    return true;
  }
  if (s == "XYH") {
    queue_motion(3, now, [this](SimTime at) {
      for (Axis* a : {&x_, &y_}) {
        a->homing.start(a->motion, at, a->home_switch, limits(*a), 0.0);
        a->endless = false;
        a->busy_until = end_of_motion(a->motion, at);
        a->move_pending = true;
      }
    });
    return true;
  }
  if (s[0] == 'X' || s[0] == 'Y') {
    if (s.size() >= 4 && s[1] == '/' && (s[2] == 'X' || s[2] == 'Y') && s[2] != s[0]) {
      const std::string_view rest = std::string_view(s).substr(3);
      if (rest == "+" || rest == "-") return true;  // ratio mode: accepted, not simulated
      if (rest.size() > 1 && rest[0] == '=') {
        const auto n = parse_number(rest.substr(1));
        if (!n || (!n->hex && n->value >= 1.0)) return false;
        const auto raw = n->hex ? static_cast<std::uint32_t>(n->value)
                                : static_cast<std::uint32_t>(n->value * 4294967296.0);
        (s[0] == 'Y' ? ratio_yx_ : ratio_xy_) = raw;
        return true;
      }
      return false;
    }
    if (motion(s, now)) return true;
    return axis_instruction(axis(s[0]), s.substr(1), now);
  }
  if (s[0] == 'P') return io_instruction(s, now);
  return false;
}

bool Cn0170Unit::query(const std::string& s, SimTime now, std::vector<std::string>& replies) {
  ++counters_.queries;
  const std::string q = s.substr(0, s.size() - 1);
  if (q == "XP" || q == "YP") {
    const Axis& a = axis(q[0]);
    const double v = a.motion.velocity(now);
    const char sign = v > kVelocityEpsilon ? '+' : v < -kVelocityEpsilon ? '-' : '=';
    std::string reply(1, q[0]);
    if (settings_.position_reply_xp) reply += 'P';
    reply += sign;
    reply += hex_field(position_register(q[0], now), 8) + "h";
    replies.push_back(reply);
    return true;
  }
  const auto quarter_steps = [](double raw_per_s) {
    return std::min<std::uint64_t>(
        0xffff, static_cast<std::uint64_t>(std::llround(std::abs(raw_per_s) / kRawPerStep * 4)));
  };
  if (q == "XV" || q == "YV") {
    replies.push_back(q + "=" + hex_field(quarter_steps(axis(q[0]).motion.velocity(now)), 4) + "h");
    return true;
  }
  if (q == "XYV") {
    const double v = std::hypot(x_.motion.velocity(now), y_.motion.velocity(now));
    replies.push_back("XYV=" + hex_field(quarter_steps(v), 4) + "h");
    return true;
  }
  if (q == "XA" || q == "YA") {
    replies.push_back(q + "=" + hex_field(static_cast<std::uint64_t>(axis(q[0]).acceleration), 4) +
                      "h");
    return true;
  }
  if (q == "XC" || q == "YC") {
    const int p = axis(q[0]).profile;
    replies.push_back(q + "=" + (p <= 16 ? std::to_string(p) : std::string(1, "LPU"[p - 17])));
    return true;
  }
  if (q == "Y/X" || q == "X/Y") {
    replies.push_back(q + "=" + hex_field(q[0] == 'Y' ? ratio_yx_ : ratio_xy_, 8) + "h");
    return true;
  }
  if (q.size() == 2 && q[0] == 'P' && q[1] >= '1' && q[1] <= '4') {
    const int n = q[1] - '0';
    const bool on = n <= 2 ? inputs_[static_cast<std::size_t>(n - 1)] : output(n);
    replies.push_back(q + "=" + (on ? "1" : "0"));
    return true;
  }
  if (q == "P") {
    const int bits = (aux_inputs_ & aux_direction_) | (aux_outputs_ & ~aux_direction_ & 0xff);
    char buf[16];
    std::snprintf(buf, sizeof buf, "P= %02Xh", bits);
    replies.push_back(buf);
    return true;
  }
  if (q == "A\\X" || q == "A\\Y" || q == "A1" || q == "A2") {
    const std::size_t i = q == "A\\X" ? 0 : q == "A\\Y" ? 1 : q == "A1" ? 2 : 3;
    char buf[16];
    std::snprintf(buf, sizeof buf, "=%02Xh", analog_[i]);
    replies.push_back(q + buf);
    return true;
  }
  if (q == "T") {
    replies.push_back(time_of_day(now));
    return true;
  }
  if (q == "D") {
    replies.push_back(date());
    return true;
  }
  --counters_.queries;
  return false;
}

bool Cn0170Unit::motion(const std::string& s, SimTime now) {
  struct Term {
    char axis;
    char op;
    Number n;
  };
  const auto term = [](std::string_view t) -> std::optional<Term> {
    if (t.size() < 3 || (t[0] != 'X' && t[0] != 'Y') ||
        std::string_view("=+-").find(t[1]) == std::string_view::npos)
      return std::nullopt;
    const auto n = parse_number(t.substr(2));
    if (!n) return std::nullopt;
    return Term{t[0], t[1], *n};
  };
  // Where a term sends its axis, from the axis state at the instant the move starts.
  const auto target = [this](const Term& t, SimTime at) {
    const Axis& a = axis(t.axis);
    const double here = a.motion.position(at);
    const double amount = t.n.hex ? t.n.value : t.n.value * kRawPerStep;
    if (t.op == '+') return here + std::round(amount);
    if (t.op == '-') return here - std::round(amount);
    // Absolute positions are unsigned registers: CW if the target is above the position.
    // Read as signed (--absolute-compare signed), a move crosses 0 instead.
    const auto target_raw = static_cast<std::uint32_t>(std::llround(amount));
    const auto from_raw = position_register(t.axis, at);
    const auto delta =
        settings_.signed_absolute
            ? static_cast<std::int64_t>(static_cast<std::int32_t>(target_raw)) -
                  static_cast<std::int64_t>(static_cast<std::int32_t>(from_raw))
            : static_cast<std::int64_t>(std::llround(amount)) - static_cast<std::int64_t>(from_raw);
    return here + static_cast<double>(delta);
  };
  const auto pair = [&](std::string_view text,
                        char separator) -> std::optional<std::pair<Term, Term>> {
    const auto at = text.find(separator);
    if (at == std::string_view::npos) return std::nullopt;
    const auto a = term(text.substr(0, at));
    const auto b = term(text.substr(at + 1));
    if (!a || !b || a->axis != 'X' || b->axis != 'Y') return std::nullopt;  // X first (p.20)
    return std::pair{*a, *b};
  };
  const auto linear = [this, target](Term tx, Term ty) {
    return [this, target, tx, ty](SimTime at) {
      const double dx = target(tx, at) - x_.motion.position(at);
      const double dy = target(ty, at) - y_.motion.position(at);
      const double length = std::hypot(dx, dy);
      if (length < 0.5) return;
      const double v = vector_max_ * kRawPerStep;
      const double acc = limits(x_).acceleration;
      // Both axes start and stop together at the vector velocity (p.22).
      if (std::abs(dx) >= 0.5)
        start_move(x_, at, x_.motion.position(at) + dx, v * std::abs(dx) / length,
                   acc * std::abs(dx) / length);
      if (std::abs(dy) >= 0.5)
        start_move(y_, at, y_.motion.position(at) + dy, v * std::abs(dy) / length,
                   acc * std::abs(dy) / length);
    };
  };
  const std::string_view text(s);
  if (const auto caret = text.find('^'); caret != std::string_view::npos) {
    // Circular interpolation: accepted, and run as a straight move to point 3.
    const auto p2 = pair(text.substr(0, caret), ',');
    const auto p3 = pair(text.substr(caret + 1), ',');
    if (!p2 || !p3) return false;
    queue_motion(3, now, linear(p3->first, p3->second));
    return true;
  }
  if (text.find('&') != std::string_view::npos) {
    const auto p = pair(text, '&');
    if (!p) return false;
    queue_motion(3, now, [this, target, p = *p](SimTime at) {
      start_move(x_, at, target(p.first, at), limits(x_).velocity, limits(x_).acceleration);
      start_move(y_, at, target(p.second, at), limits(y_).velocity, limits(y_).acceleration);
    });
    return true;
  }
  if (text.find(',') != std::string_view::npos) {
    if (s.size() > 1 && s[1] == 'V') return false;  // XV=b,m
    const auto p = pair(text, ',');
    if (!p) return false;
    queue_motion(3, now, linear(p->first, p->second));
    return true;
  }
  const auto t = term(text);
  if (!t) return false;
  queue_motion(t->axis == 'X' ? 1 : 2, now, [this, target, t = *t](SimTime at) {
    Axis& a = axis(t.axis);
    start_move(a, at, target(t, at), limits(a).velocity, limits(a).acceleration);
  });
  return true;
}

bool Cn0170Unit::axis_instruction(Axis& a, const std::string& rest, SimTime now) {
  const unsigned mask = a.letter == 'X' ? 1 : 2;
  const std::string_view r(rest);
  if (r == "H") {
    queue_motion(mask, now, [this, &a](SimTime at) {
      a.homing.start(a.motion, at, a.home_switch, limits(a), 0.0);
      a.endless = false;
      a.busy_until = end_of_motion(a.motion, at);
      a.move_pending = true;
    });
    return true;
  }
  if (r.rfind("++", 0) == 0 || r.rfind("--", 0) == 0) {
    std::optional<double> speed = a.max_velocity;
    if (r.size() > 2) speed = velocity_of(r.substr(2), 0);
    if (!speed) return false;
    const double v = (r[0] == '+' ? 1 : -1) * *speed * kRawPerStep;
    queue_motion(mask, now, [this, &a, v](SimTime at) { start_speed(a, at, v); });
    return true;
  }
  if (r.size() == 2 && (r[1] == '+' || r[1] == '-')) {
    // The axis's switches, each turned on by its letter and '+', off by its letter and '-'.
    static constexpr std::pair<char, bool Axis::*> kSwitches[] = {
        {'H', &Axis::home_cw}, {'P', &Axis::position_trigger}, {'V', &Axis::velocity_trigger},
        {'L', &Axis::io_link}, {'B', &Axis::handshake},        {'M', &Axis::modulo_quit}};
    for (const auto& [letter, flag] : kSwitches) {
      if (r[0] != letter) continue;
      a.*flag = r[1] == '+';
      return true;
    }
    return false;
  }
  if (r.rfind("P=", 0) == 0) {
    const auto n = parse_number(r.substr(2));
    if (!n) return false;
    const double value = n->hex ? n->value : std::round(n->value * kRawPerStep);
    if (value > 4294967295.0) return false;
    const double here = a.motion.position(now);
    a.motion.set_position(now, value);
    a.home_switch += value - here;
    return true;
  }
  if (r.rfind("V=", 0) == 0) {
    const auto pair = velocity_pair_of(r.substr(2));
    if (!pair) return false;
    if (pair->base) a.base_velocity = *pair->base;
    if (pair->max) a.max_velocity = *pair->max;
    return true;
  }
  if (r.rfind("A=", 0) == 0) {
    const auto n = parse_number(r.substr(2));
    if (!n) return false;
    const long reg = n->hex ? std::lround(n->value) : std::lround(n->value / 64.0);
    if (reg < 1) return false;  // 0 is not allowed (p.31)
    a.acceleration = static_cast<int>(std::min(reg, 65535L));
    return true;
  }
  if (r.rfind("C(", 0) == 0) {
    const auto close = r.find(")=");
    if (close == std::string_view::npos) return false;
    const auto i = parse_small(r.substr(2, close - 2), 1, 16);
    const auto n = parse_number(r.substr(close + 2));
    if (!i || !n || n->value > 255) return false;
    a.user_profile[static_cast<std::size_t>(*i - 1)] = static_cast<int>(n->value);
    return true;
  }
  if (r == "C\\L" || r == "C\\P" || r == "C\\U") {
    a.profile = r[2] == 'L' ? 17 : r[2] == 'P' ? 18 : 19;
    return true;
  }
  if (r.size() >= 2 && r[0] == 'C') {
    const auto n = parse_small(r.substr(1), 1, 16);
    if (!n) return false;
    a.profile = *n;
    return true;
  }
  if (r.size() >= 2 && r[0] == 'R') {
    const auto n = parse_small(r.substr(1), 1, 125);
    if (!n || (*n != 1 && *n != 2 && *n != 10 && *n != 125)) return false;
    a.resolution = *n;
    return true;
  }
  if (r.rfind("I=", 0) == 0) {
    const auto n = parse_small(r.substr(2), 0, 255);
    if (!n) return false;
    a.standby_delay = *n;
    return true;
  }
  if (r.size() == 2 && r[0] == 'J') {
    const auto n = parse_small(r.substr(1), 0, 7);
    if (!n) return false;
    a.joystick = *n;
    if (*n == 0) {
      if (a.endless) start_speed(a, now, 0.0);
      a.endless = false;
    } else {
      set_analog(a.letter, analog_[a.letter == 'X' ? 0 : 1], now);
    }
    return true;
  }
  return false;
}

bool Cn0170Unit::io_instruction(const std::string& s, SimTime) {
  const std::string_view r(s);
  if ((r == "P3=0" || r == "P3=1" || r == "P4=0" || r == "P4=1")) {
    outputs_[static_cast<std::size_t>(r[1] - '3')] = r[3] == '1';
    return true;
  }
  const auto byte = [](std::string_view text) -> std::optional<int> {
    const auto n = parse_number(text);
    if (!n || !n->hex || n->value > 255) return std::nullopt;  // upper-case H required
    return static_cast<int>(n->value);
  };
  if (r == "P\\I") {
    aux_direction_ = 0xff;
    return true;
  }
  if (r == "P\\O") {
    aux_direction_ = 0;
    return true;
  }
  if (r.rfind("P\\", 0) == 0) {
    const auto b = byte(r.substr(2));
    if (!b) return false;
    aux_direction_ = *b;
    return true;
  }
  std::optional<int> b;
  if (r.rfind("P||", 0) == 0 && (b = byte(r.substr(3)))) {
    aux_outputs_ ^= *b;
  } else if (r.rfind("P|", 0) == 0 && (b = byte(r.substr(2)))) {
    aux_outputs_ |= *b;
  } else if (r.rfind("P&", 0) == 0 && (b = byte(r.substr(2)))) {
    aux_outputs_ &= *b;
  } else if (r.rfind("P=", 0) == 0 && (b = byte(r.substr(2)))) {
    aux_outputs_ = *b;
  } else {
    return false;
  }
  aux_outputs_ &= 0xff;
  return true;
}

}  // namespace fieldgate::sim::centent
