#include "sim/techno/controller.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "sim/common/control_channel.hpp"
#include "sim/common/line_device_loop.hpp"

namespace fieldgate::sim::techno {
namespace {

constexpr std::int64_t kMaxSteps = 8'000'000;
constexpr std::int64_t kMinSpeed = 30;
constexpr std::int64_t kMaxSpeed = 10'000;
constexpr double kPi = 3.14159265358979323846;

// Comma- or space-separated integers; a leading comma is tolerated (the manual's `@0Y,9599,…`).
std::optional<std::vector<std::int64_t>> parse_numbers(std::string_view text) {
  std::vector<std::int64_t> values;
  std::size_t i = 0;
  const auto skip_spaces = [&] {
    while (i < text.size() && text[i] == ' ') ++i;
  };
  skip_spaces();
  if (i < text.size() && text[i] == ',') ++i;
  while (true) {
    skip_spaces();
    if (i == text.size()) return values;
    std::size_t begin = i;
    if (text[i] == '+' || text[i] == '-') ++i;
    const std::size_t digits = i;
    while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) ++i;
    if (i == digits) return std::nullopt;
    std::string_view token = text.substr(begin, i - begin);
    if (token.front() == '+') token.remove_prefix(1);
    std::int64_t v = 0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    if (ec != std::errc{} || end != token.data() + token.size()) return std::nullopt;
    values.push_back(v);
    skip_spaces();
    if (i < text.size()) {
      if (text[i] == ',')
        ++i;
      else if (text[i - 1] != ' ')
        return std::nullopt;
    }
  }
}

int move_value_count(int axes) {
  return axes == 1 ? 2 : axes == 3 ? 4 : axes == 5 ? 6 : axes == 7 ? 8 : 0;
}

int axis_count(int axes) {
  return (axes & 1) + ((axes >> 1) & 1) + ((axes >> 2) & 1);
}

// Which axis each value pair drives (same reading as the driver, digest §2).
std::vector<int> pair_axes(int axes, int plane) {
  switch (axes) {
    case 1:
      return {0};
    case 3:
      return {0, 1};
    case 5:
      return {0, 2, 2};
    case 7:
      if (plane == 1) return {0, 2, 1, 1};
      if (plane == 2) return {1, 2, 0, 0};
      return {0, 1, 2, 2};
    default:
      return {};
  }
}

// Pairs moved together: the plane pair (all three in 3-axis interpolation), then each further
// pair on its own.
std::vector<std::vector<std::size_t>> pair_groups(int axes, bool interpolation_3d) {
  switch (axes) {
    case 1:
      return {{0}};
    case 3:
      return {{0, 1}};
    case 5:
      return {{0}, {1}, {2}};
    default:
      if (interpolation_3d) return {{0, 1, 2}, {3}};
      return {{0, 1}, {2}, {3}};
  }
}

// A trapezoid from rest to rest, as MotionAxis plans it with equal ramps.
double trapezoid_seconds(double distance, double speed, double acceleration) {
  distance = std::abs(distance);
  if (distance <= 0) return 0;
  if (distance >= speed * speed / acceleration) return distance / speed + speed / acceleration;
  return 2 * std::sqrt(distance / acceleration);
}

SimTime after(SimTime t, double seconds) {
  // A microsecond late rather than early: the axis is surely at rest when its leg ends.
  return t +
         std::chrono::duration_cast<SimClock::duration>(std::chrono::duration<double>(seconds)) +
         std::chrono::microseconds(1);
}

bool all_digits(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c)) != 0;
  });
}

std::string hex2(int value) {
  char out[8];
  std::snprintf(out, sizeof out, "%02X", value & 0xff);
  return out;
}

}  // namespace

std::optional<Variant> parse_variant(std::string_view text) {
  if (text == "it116g") return Variant::it116g;
  if (text == "c10") return Variant::c10;
  if (text == "c116") return Variant::c116;
  if (text == "c142") return Variant::c142;
  return std::nullopt;
}

std::string encode_positions(const std::array<std::int64_t, 3>& steps) {
  std::string out;
  for (const std::int64_t v : steps) {
    char field[8];
    std::snprintf(field, sizeof field, "%06X", static_cast<unsigned>(v) & 0xffffffu);
    out += field;
  }
  return out;
}

Controller::Controller(ControllerOptions options, SimTime now) : options_(options) {
  axes_ = options_.axes;
  for (std::size_t i = 0; i < 3; ++i) {
    axes_motion_[i].set_position(now, options_.home_distance);
    origin_[i] = options_.home_distance;
  }
}

std::int64_t Controller::position(int axis, SimTime now) const {
  const auto i = static_cast<std::size_t>(axis);
  return static_cast<std::int64_t>(std::llround(axes_motion_[i].position(now) - origin_[i]));
}

void Controller::reply(SimTime at, char code) {
  if (emit_) emit_(at, std::string(1, code));
}

void Controller::reply_data(SimTime at, std::string data) {
  std::string out = options_.position_ack ? "0" : "";
  out += data;
  if (options_.reply_cr) out += '\r';
  if (emit_) emit_(at, std::move(out));
}

void Controller::line(std::string_view text, SimTime now) {
  advance(now);
  if (program_mode_ && busy_ == Busy::idle) {
    ++counters_.lines;
    ++counters_.commands;
    counters_.last_command = std::string(text);
    execute_program_line(text, now);
    return;
  }
  if (text.empty()) return;  // a blank line, e.g. an LF sent on its own
  if (text.front() != '@') {
    ++counters_.lines;
    ++counters_.commands;
    counters_.last_command = std::string(text);
    reply(now, '5');
    return;
  }
  if (text.size() >= 2 && std::isdigit(static_cast<unsigned char>(text[1])) &&
      text[1] - '0' != options_.device) {
    ++counters_.other_device;  // not addressed to this controller: it stays silent
    return;
  }
  ++counters_.lines;
  counters_.last_command = std::string(text);
  std::string_view body = text.size() >= 2 ? text.substr(2) : std::string_view{};
  while (!body.empty() && body.front() == ' ') body.remove_prefix(1);  // `@0 i` (p.43)
  const bool query =
      !body.empty() && (body.front() == 'P' || body.front() == 'b' || body.front() == 'c');
  ++(query ? counters_.queries : counters_.commands);
  if (text.size() < 2) {
    reply(now, '\r');
    return;
  }
  if (!std::isdigit(static_cast<unsigned char>(text[1]))) {
    reply(now, '5');
    return;
  }
  if (body.empty()) {
    reply(now, '\r');  // "unexpected end of command"
    return;
  }
  if (busy_ != Busy::idle) {
    if (query && busy_ == Busy::lower_case && options_.queries_during_motion) {
      execute(body, now);
      return;
    }
    // One command at a time: what arrives during a motion waits for its end (p.41, p.73).
    buffered_.emplace_back(body);
    return;
  }
  execute(body, now);
}

void Controller::execute(std::string_view body, SimTime now) {
  if (all_digits(body)) {
    const auto axes = parse_numbers(body);
    const std::int64_t a = axes && axes->size() == 1 ? (*axes)[0] : 0;
    const bool valid =
        options_.variant == Variant::it116g ? a == 1 : (a == 1 || a == 3 || a == 5 || a == 7);
    if (!valid) {
      reply(now, '3');
      return;
    }
    axes_ = static_cast<int>(a);
    program_.clear();  // "the memory is cleared and partitioned" (p.69)
    plane_ = 0;
    interpolation_3d_ = false;
    for (std::size_t i = 0; i < 3; ++i) origin_[i] = axes_motion_[i].position(now);
    reply(now, '0');
    return;
  }
  if (axes_ == 0) {
    reply(now, '4');
    return;
  }
  const char letter = body.front();
  const std::string_view rest = body.substr(1);
  const bool c142 = options_.variant == Variant::c142;
  switch (letter) {
    case 'A':
    case 'a':
    case 'M':
    case 'm': {
      std::deque<Leg> legs;
      const bool relative = letter == 'A' || letter == 'a';
      if (const auto error = plan_move(rest, relative, legs, now)) {
        reply(now, *error);
        return;
      }
      start_job(std::move(legs), std::isupper(static_cast<unsigned char>(letter)) != 0, now);
      return;
    }
    case 'R':
    case 'r': {
      const auto v = parse_numbers(rest);
      std::deque<Leg> legs;
      if (!v || v->size() != 1) {
        reply(now, '3');
        return;
      }
      if (const auto error = plan_home((*v)[0], legs)) {
        reply(now, *error);
        return;
      }
      start_job(std::move(legs), letter == 'R', now);
      return;
    }
    case 'n': {
      const auto v = parse_numbers(rest);
      if (!v || v->size() != 1 || (*v)[0] < 1 || (*v)[0] > 7 || ((*v)[0] & ~axes_)) {
        reply(now, '3');  // "axes were not defined" (p.79)
        return;
      }
      for (int i = 0; i < 3; ++i)
        if ((*v)[0] & (1 << i)) origin_[static_cast<std::size_t>(i)] = machine(i, now);
      reply(now, '0');
      return;
    }
    case 'd': {
      const auto v = parse_numbers(rest);
      if (!v) {
        reply(now, '5');
        return;
      }
      if (static_cast<int>(v->size()) != axis_count(axes_)) {
        reply(now, '7');
        return;
      }
      for (const auto s : *v)
        if (s < kMinSpeed || s > kMaxSpeed) {
          reply(now, 'D');
          return;
        }
      std::size_t next = 0;
      for (int i = 0; i < 3; ++i)
        if (defined(i))
          home_speed_[static_cast<std::size_t>(i)] = static_cast<double>((*v)[next++]);
      reply(now, '0');
      return;
    }
    case 'P': {
      if (!rest.empty()) {
        reply(now, '5');
        return;
      }
      reply_data(now, encode_positions({position(0, now), position(1, now), position(2, now)}));
      return;
    }
    case 'b':
    case 'c': {
      const auto v = parse_numbers(rest);
      if (!v || v->size() != 1 || (*v)[0] < 0 || (*v)[0] > 65535) {
        reply(now, '5');
        return;
      }
      int value = 0;
      if (letter == 'b' && (*v)[0] == 65531) value = inputs_;
      if (letter == 'b' && (*v)[0] == 65529) value = outputs_[0];
      if (letter == 'b' && (*v)[0] == 65530) value = outputs_[1];
      // Peek answers with the handshake first, then two hex digits (p.54).
      std::string out = "0" + hex2(value);
      if (options_.reply_cr) out += '\r';
      if (emit_) emit_(now, std::move(out));
      return;
    }
    case 'B': {
      const auto v = parse_numbers(rest);
      if (!v || v->size() != 2 || (*v)[0] < 0 || (*v)[0] > 65535) {
        reply(now, '5');
        return;
      }
      if ((*v)[1] < 0 || (*v)[1] > 255) {
        reply(now, '7');
        return;
      }
      if ((*v)[0] == 65529) outputs_[0] = static_cast<int>((*v)[1]);
      if ((*v)[0] == 65530) outputs_[1] = static_cast<int>((*v)[1]);
      reply(now, '0');
      return;
    }
    case 'e': {
      const auto v = parse_numbers(rest);
      if (!v || v->size() != 1 || (*v)[0] < 0 || (*v)[0] > 2) {
        reply(now, '7');
        return;
      }
      plane_ = static_cast<int>((*v)[0]);
      reply(now, '0');
      return;
    }
    case 'z':
    case 'f': {
      const auto v = parse_numbers(rest);
      if (!c142) {
        reply(now, '5');  // interface card 4.0 and the IT116G do not know the command
        return;
      }
      const std::int64_t lo = letter == 'z' ? 0 : -1;
      const std::int64_t hi = letter == 'z' ? 1 : 0;
      if (!v || v->size() != 1 || (*v)[0] < lo || (*v)[0] > hi) {
        reply(now, '7');
        return;
      }
      if (letter == 'z')
        interpolation_3d_ = (*v)[0] == 1;
      else
        circle_direction_ = static_cast<int>((*v)[0]);
      reply(now, '0');
      return;
    }
    case 'Y': {
      if (!c142) {
        reply(now, '5');
        return;
      }
      const auto v = parse_numbers(rest);
      if (!v) {
        reply(now, '5');
        return;
      }
      if (v->size() != 7 || (*v)[0] < 1 || std::llabs((*v)[5]) != 1 || std::llabs((*v)[6]) != 1) {
        reply(now, '7');
        return;
      }
      if ((*v)[1] < kMinSpeed || (*v)[1] > kMaxSpeed) {
        reply(now, 'D');
        return;
      }
      std::deque<Leg> legs;
      if (const auto error = plan_arc(*v, legs, now)) {
        reply(now, *error);
        return;
      }
      start_job(std::move(legs), true, now);
      return;
    }
    case 'S':
    case 's': {
      std::deque<Leg> legs;
      if (const auto error = plan_program(legs, now)) {
        reply(now, *error);
        return;
      }
      start_job(std::move(legs), letter == 'S', now);
      return;
    }
    case 'k':
      program_.clear();
      reply(now, '0');
      return;
    case 'i':
      program_.clear();
      program_mode_ = true;
      reply(now, '0');
      return;
    case 'u':
      reply(now, '0');  // nothing to save: the simulator has no memory card
      return;
    default:
      reply(now, '5');  // includes `t`: trace is not simulated
      return;
  }
}

void Controller::execute_program_line(std::string_view text, SimTime now) {
  if (text.empty()) return;
  const char op = text.front();
  const auto fail = [&](char code) {
    reply(now, code);
    program_mode_ = false;  // a download error returns to immediate mode (digest §8.6)
  };
  if (op == '9') {
    program_mode_ = false;
    reply(now, '0');
    return;
  }
  const auto v = parse_numbers(text.substr(1));
  switch (op) {
    case '0':
    case '6':
    case 'M':
    case 'm': {
      if (!v) return fail('5');
      if (static_cast<int>(v->size()) != move_value_count(axes_)) return fail('7');
      for (std::size_t i = 0; i < v->size(); ++i) {
        if (i % 2 == 1 && ((*v)[i] < kMinSpeed || (*v)[i] > kMaxSpeed)) return fail('D');
        if (i % 2 == 0 && std::llabs((*v)[i]) > kMaxSteps) return fail('5');
      }
      break;
    }
    case '7':
    case 'n':
      if (!v || v->size() != 1 || (*v)[0] < 1 || (*v)[0] > 7 || ((*v)[0] & ~axes_))
        return fail('3');
      break;
    case '5':
      if (!v || v->size() != 1 || (*v)[0] < 0 || (*v)[0] > 32767) return fail('5');
      break;
    case '1':
    case '2':
    case '3':
    case '4':
    case 'o':
    case 'p':
    case 'e':
    case 'z':
    case 'f':
    case 'Y':
      break;  // stored; the simulator does not run them
    default:
      return fail('5');
  }
  program_.emplace_back(text);
  reply(now, '0');
}

std::optional<char> Controller::plan_move(std::string_view text, bool relative,
                                          std::deque<Leg>& legs, SimTime now) const {
  const auto v = parse_numbers(text);
  if (!v) return '5';
  if (static_cast<int>(v->size()) != move_value_count(axes_)) return '7';
  for (std::size_t i = 0; i < v->size(); ++i) {
    if (i % 2 == 1 && ((*v)[i] < kMinSpeed || (*v)[i] > kMaxSpeed)) return 'D';
    if (i % 2 == 0 && std::llabs((*v)[i]) > kMaxSteps) return '5';
  }
  if (estop_) return '2';
  const auto axes_of_pair = pair_axes(axes_, plane_);
  std::array<double, 3> rest{};
  for (std::size_t i = 0; i < 3; ++i) rest[i] = axes_motion_[i].rest_position(now);
  for (const auto& group : pair_groups(axes_, interpolation_3d_)) {
    Leg leg;
    leg.relative = relative;
    for (const std::size_t pair : group) {
      const auto axis = static_cast<std::size_t>(axes_of_pair[pair]);
      const auto g = static_cast<double>((*v)[2 * pair]);
      leg.value[axis] = g;
      leg.speed[axis] = static_cast<double>((*v)[2 * pair + 1]);
      rest[axis] = relative ? rest[axis] + g : origin_[axis] + g;
      // "The requested motion lies outside the reach of one of the axes" (p.32, p.46).
      if (rest[axis] < -0.5 || rest[axis] > options_.travel + 0.5) return '2';
    }
    legs.push_back(leg);
  }
  return std::nullopt;
}

std::optional<char> Controller::plan_home(int64_t mask, std::deque<Leg>& legs) const {
  if (mask < 1 || mask > 7 || (mask & ~axes_)) return '3';
  if (estop_) return '2';
  // A combined home runs Z, then Y, then X (p.41).
  for (int axis = 2; axis >= 0; --axis) {
    if (!(mask & (1 << axis))) continue;
    Leg leg;
    leg.kind = Leg::Kind::home;
    leg.axis = axis;
    legs.push_back(leg);
  }
  return std::nullopt;
}

std::optional<char> Controller::plan_arc(const std::vector<std::int64_t>& v, std::deque<Leg>& legs,
                                         SimTime) const {
  if (estop_) return '2';
  const double length = static_cast<double>(v[0]);
  const double speed = static_cast<double>(v[1]);
  const double x0 = static_cast<double>(v[3]);
  const double y0 = static_cast<double>(v[4]);
  const double radius = std::hypot(x0, y0);
  if (radius < 1) return '7';
  // Walk the circle until the summed X and Y travel reaches B (B = DX + DY, p.35).
  const double direction = circle_direction_ == -1 ? 1.0 : -1.0;
  const double step = std::max(1.0 / radius, 2 * kPi / 200'000);
  double angle = std::atan2(y0, x0);
  double x = x0, y = y0, travelled = 0;
  for (int i = 0; i < 2'000'000 && travelled < length; ++i) {
    angle += direction * step;
    const double nx = radius * std::cos(angle), ny = radius * std::sin(angle);
    travelled += std::abs(nx - x) + std::abs(ny - y);
    x = nx;
    y = ny;
  }
  const double dx = std::round(x - x0), dy = std::round(y - y0);
  const double total = std::max(1.0, std::abs(dx) + std::abs(dy));
  Leg leg;
  leg.value[0] = dx;
  leg.value[1] = dy;
  leg.speed[0] = std::max(1.0, speed * std::abs(dx) / total);
  leg.speed[1] = std::max(1.0, speed * std::abs(dy) / total);
  legs.push_back(leg);
  return std::nullopt;
}

std::optional<char> Controller::plan_program(std::deque<Leg>& legs, SimTime now) const {
  if (program_.empty()) return 'G';
  for (const std::string& line : program_) {
    const char op = line.front();
    const std::string_view rest = std::string_view(line).substr(1);
    const auto v = parse_numbers(rest);
    if (op == '0' || op == '6' || op == 'M' || op == 'm') {
      const auto axes_of_pair = pair_axes(axes_, plane_);
      for (const auto& group : pair_groups(axes_, interpolation_3d_)) {
        Leg leg;
        leg.relative = op == '0' || op == '6';
        for (const std::size_t pair : group) {
          const auto axis = static_cast<std::size_t>(axes_of_pair[pair]);
          leg.value[axis] = static_cast<double>((*v)[2 * pair]);
          leg.speed[axis] = static_cast<double>((*v)[2 * pair + 1]);
        }
        legs.push_back(leg);
      }
    } else if (op == '7') {
      plan_home((*v)[0], legs);
    } else if (op == '5') {
      Leg leg;
      leg.kind = Leg::Kind::delay;
      leg.seconds = static_cast<double>((*v)[0]) * 0.1;
      legs.push_back(leg);
    } else if (op == 'n') {
      for (int axis = 0; axis < 3; ++axis) {
        if (!((*v)[0] & (1 << axis))) continue;
        Leg leg;
        leg.kind = Leg::Kind::zero;
        leg.axis = axis;
        legs.push_back(leg);
      }
    }
  }
  (void)now;
  return std::nullopt;
}

void Controller::start_job(std::deque<Leg> legs, bool capital, SimTime now) {
  if (!capital) reply(now, '0');  // lower case: acknowledged at the start (p.29)
  job_ = Job{};
  job_->legs = std::move(legs);
  job_->capital = capital;
  busy_ = capital ? Busy::capital : Busy::lower_case;
  stop_presses_ = 0;
  stopped_capital_ = false;
  start_leg(now);
}

void Controller::start_leg(SimTime now) {
  job_->homing_axis.reset();
  job_->endless_home = false;
  if (job_->legs.empty()) {
    job_->leg_end = now;
    return;
  }
  const Leg leg = job_->legs.front();
  job_->legs.pop_front();
  const double a = options_.acceleration;
  double seconds = 0;
  switch (leg.kind) {
    case Leg::Kind::move:
      for (std::size_t i = 0; i < 3; ++i) {
        if (!leg.value[i]) continue;
        MotionAxis& axis = axes_motion_[i];
        const double from = axis.position(now);
        double target = leg.relative ? from + *leg.value[i] : origin_[i] + *leg.value[i];
        if (i == 0 && limit_x_ &&
            ((from < *limit_x_ && target >= *limit_x_) ||
             (from > *limit_x_ && target <= *limit_x_))) {
          target = *limit_x_;  // the switch stops the axis there
          job_->limit_hit = true;
        }
        const double distance = std::abs(target - from);
        if (distance < 0.5) continue;
        axis.start_move(now, target, {leg.speed[i], a, a});
        seconds = std::max(seconds, trapezoid_seconds(distance, leg.speed[i], a));
      }
      break;
    case Leg::Kind::home: {
      const auto i = static_cast<std::size_t>(leg.axis);
      const double speed = home_speed_[i];
      job_->homing_axis = leg.axis;
      if (!options_.mechanics) {
        // No switch will ever be found: it keeps searching and never answers (p.41).
        axes_motion_[i].start_velocity(now, -speed, a, a);
        job_->endless_home = true;
        return;
      }
      const double from = axes_motion_[i].position(now);
      if (std::abs(from) >= 0.5) {
        axes_motion_[i].start_move(now, 0.0, {speed, a, a});
        seconds = trapezoid_seconds(from, speed, a);
      }
      break;
    }
    case Leg::Kind::delay:
      seconds = leg.seconds;
      break;
    case Leg::Kind::zero: {
      const auto i = static_cast<std::size_t>(leg.axis);
      origin_[i] = axes_motion_[i].position(now);
      break;
    }
  }
  job_->leg_end = after(now, seconds);
}

void Controller::finish_leg(SimTime at) {
  if (job_->homing_axis) {
    // At the switch: that is the reference point, position 0.
    const auto i = static_cast<std::size_t>(*job_->homing_axis);
    axes_motion_[i].set_position(at, 0.0);
    origin_[i] = 0.0;
    job_->homing_axis.reset();
  }
}

void Controller::finish_job(SimTime at) {
  if (job_->limit_hit && busy_ != Busy::stopping) {
    // Capital: `2` instead of the acknowledge; lower case: `2` after the `0` of the start.
    reply(at, '2');
  } else if (busy_ == Busy::stopping) {
    if (stopped_capital_ && options_.stop_acknowledges) reply(at, '0');
  } else if (job_->capital) {
    reply(at, '0');  // capital: acknowledged at the end of the motion
  }
  job_.reset();
  busy_ = Busy::idle;
  run_buffered(at);
}

void Controller::run_buffered(SimTime at) {
  while (busy_ == Busy::idle && !buffered_.empty()) {
    const std::string body = std::move(buffered_.front());
    buffered_.pop_front();
    execute(body, at);
  }
}

void Controller::advance(SimTime now) {
  while (job_ && !job_->endless_home && job_->leg_end <= now) {
    const SimTime at = job_->leg_end;
    if (busy_ != Busy::stopping) finish_leg(at);
    if (busy_ != Busy::stopping && !job_->legs.empty() && !job_->limit_hit) {
      start_leg(at);
      continue;
    }
    finish_job(at);
  }
}

std::optional<SimTime> Controller::next_event() const {
  if (!job_ || job_->endless_home) return std::nullopt;
  return job_->leg_end;
}

void Controller::stop_byte(SimTime now) {
  advance(now);
  ++counters_.stops;
  if (job_ && busy_ != Busy::stopping) {
    // Homing without mechanics: "the STOP button must be pushed twice to exit" (p.41).
    if (job_->endless_home && ++stop_presses_ < 2) return;
    double ramp = 0;
    for (auto& axis : axes_motion_) {
      const double v = axis.velocity(now);
      if (v != 0) {
        axis.abort(now, options_.acceleration);
        ramp = std::max(ramp, std::abs(v) / options_.acceleration);
      }
    }
    stopped_capital_ = job_->capital;
    job_->legs.clear();
    job_->homing_axis.reset();
    job_->endless_home = false;
    job_->leg_end = after(now, ramp);
    busy_ = Busy::stopping;
    return;
  }
  // "In case another command is in the buffer, the Stop Execution command should be entered a
  // second time, otherwise the buffered command will start running" (p.73).
  buffered_.clear();
}

void Controller::reset_byte(SimTime now) {
  advance(now);
  ++counters_.resets;
  for (auto& axis : axes_motion_) axis.stop(now);  // no deceleration (p.68)
  job_.reset();
  busy_ = Busy::idle;
  buffered_.clear();
  program_mode_ = false;
}

std::optional<std::string> Controller::control(std::string_view verb,
                                               std::span<const std::string> arguments,
                                               SimTime now) {
  advance(now);
  const auto on_off = [&](bool& flag, bool inverted) -> std::string {
    if (arguments.size() != 1 || (arguments[0] != "on" && arguments[0] != "off"))
      return "error: usage: " + std::string(verb) + " on|off";
    flag = (arguments[0] == "on") != inverted;
    return "ok " + std::string(verb) + " " + arguments[0];
  };
  if (verb == "mechanics") return on_off(options_.mechanics, false);
  if (verb == "estop") return on_off(estop_, false);
  if (verb == "limit") {
    if (arguments.size() != 1) return std::string("error: limit POSITION|off");
    if (arguments[0] == "off") {
      limit_x_.reset();
      return std::string("ok limit off");
    }
    char* end = nullptr;
    const double at = std::strtod(arguments[0].c_str(), &end);
    if (end == arguments[0].c_str() || *end) return std::string("error: limit POSITION|off");
    limit_x_ = at;
    return "ok limit " + arguments[0];
  }
  if (verb == "inputs") {
    const auto mask = arguments.size() == 1 ? parse_control_integer(arguments[0]) : std::nullopt;
    if (!mask || *mask < 0 || *mask > 255) return "error: usage: inputs MASK (0-255, 1 = open)";
    inputs_ = static_cast<int>(*mask);
    return "ok inputs " + arguments[0];
  }
  if (verb == "power-cycle") {
    for (std::size_t i = 0; i < 3; ++i) {
      axes_motion_[i].stop(now);
      origin_[i] = axes_motion_[i].position(now);
    }
    job_.reset();
    busy_ = Busy::idle;
    buffered_.clear();
    axes_ = 0;
    home_speed_ = {2000, 2000, 2000};
    plane_ = 0;
    interpolation_3d_ = false;
    outputs_ = {};
    program_mode_ = false;
    // Without the battery-backed RAM option the program is lost as well.
    program_.clear();
    return "ok power-cycle";
  }
  if (verb == "counters") {
    const auto& c = counters_;
    return "ok counters lines=" + std::to_string(c.lines) +
           " queries=" + std::to_string(c.queries) + " commands=" + std::to_string(c.commands) +
           " stops=" + std::to_string(c.stops) + " resets=" + std::to_string(c.resets) +
           " other_device=" + std::to_string(c.other_device) +
           " last=" + escape_bytes(c.last_command);
  }
  if (verb == "state") {
    static constexpr const char* kBusy[] = {"idle", "capital", "lower-case", "stopping"};
    return "ok state axes=" + std::to_string(axes_) + " busy=" + kBusy[static_cast<int>(busy_)] +
           " x=" + std::to_string(position(0, now)) + " y=" + std::to_string(position(1, now)) +
           " z=" + std::to_string(position(2, now)) +
           " buffered=" + std::to_string(buffered_.size()) +
           " program_lines=" + std::to_string(program_.size()) +
           " outputs=" + std::to_string(outputs_[0]) + "," + std::to_string(outputs_[1]);
  }
  return std::nullopt;
}

std::string Controller::control_help() {
  return "mechanics on|off homing finds its switch / never ends and never answers (manual p.41)\n"
         "estop on|off     moves and homing answer 2 (emergency stop or limit switch)\n"
         "inputs MASK      input port byte read by b65531 (1 = open, default 255)\n"
         "power-cycle      axes undefined (everything answers 4 until @0<axes>), defaults back\n"
         "counters         lines, queries, commands, stops, resets received; the last line\n"
         "state            axes, busy, positions, buffered lines, program lines, outputs\n";
}

}  // namespace fieldgate::sim::techno
