#include "sim/common/motion_axis.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace fieldgate::sim {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Below this distance (counts) a move counts as already being at its target.
constexpr double kDistanceEpsilon = 1e-9;
// Re-issuing a move while braking onto the same target must not read as an overshoot because of
// rounding in the stopping distance.
constexpr double kStoppingSlack = 1e-6;

double sign(double x) {
  return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0);
}

void require_positive(double value, const char* what) {
  if (!(value > 0) || !std::isfinite(value)) {
    throw std::invalid_argument(std::string(what) + " must be positive and finite");
  }
}

}  // namespace

std::int64_t MotionAxis::position_counts(SimTime now) const {
  return static_cast<std::int64_t>(std::llround(position(now)));
}

bool MotionAxis::in_motion(SimTime now) const {
  if (endless_) return true;
  const double elapsed = std::chrono::duration<double>(now - start_time_).count();
  return elapsed < duration_;
}

double MotionAxis::rest_position(SimTime now) const {
  return endless_ ? position(now) : rest_;
}

MotionAxis::State MotionAxis::evaluate(SimTime now) const {
  double t = std::max(0.0, std::chrono::duration<double>(now - start_time_).count());
  double p = start_position_;
  double v = start_velocity_;
  for (const Segment& segment : segments_) {
    const double a = segment.acceleration;
    if (t < segment.duration) return {p + v * t + 0.5 * a * t * t, v + a * t, a};
    p += v * segment.duration + 0.5 * a * segment.duration * segment.duration;
    v += a * segment.duration;
    t -= segment.duration;
  }
  return {rest_, 0.0, 0.0};
}

void MotionAxis::restart(SimTime now, State from) {
  start_time_ = now;
  start_position_ = from.position;
  start_velocity_ = from.velocity;
  segments_.clear();
  duration_ = 0.0;
  endless_ = false;
}

void MotionAxis::append(double duration, double acceleration) {
  if (!(duration > 0)) return;
  segments_.push_back({duration, acceleration});
  if (std::isinf(duration)) {
    endless_ = true;
  } else {
    duration_ += duration;
  }
}

void MotionAxis::finish(bool snap_to_target, double target) {
  double p = start_position_;
  double v = start_velocity_;
  for (const Segment& segment : segments_) {
    if (std::isinf(segment.duration)) break;
    p += v * segment.duration + 0.5 * segment.acceleration * segment.duration * segment.duration;
    v += segment.acceleration * segment.duration;
  }
  rest_ = snap_to_target ? target : p;
}

void MotionAxis::plan_forward(double direction, double speed, double distance,
                              const MoveLimits& limits) {
  const double a = limits.acceleration;
  const double d = limits.deceleration;
  const double vmax = limits.velocity;
  if (speed * speed / (2 * d) >= distance) {
    // Only reachable within rounding of the caller's check: brake exactly onto the target.
    if (distance > 0 && speed > 0) {
      const double exact = speed * speed / (2 * distance);
      append(speed / exact, -direction * exact);
    }
    return;
  }
  if (speed > vmax) {
    const double cruise =
        distance - (speed * speed - vmax * vmax) / (2 * d) - vmax * vmax / (2 * d);
    append((speed - vmax) / d, -direction * d);
    append(cruise / vmax, 0.0);
    append(vmax / d, -direction * d);
    return;
  }
  // Peak speed of a triangle that accelerates from `speed` and brakes to zero over `distance`.
  const double peak = std::sqrt((2 * a * d * distance + d * speed * speed) / (a + d));
  if (peak <= vmax) {
    append((peak - speed) / a, direction * a);
    append(peak / d, -direction * d);
    return;
  }
  const double cruise = distance - (vmax * vmax - speed * speed) / (2 * a) - vmax * vmax / (2 * d);
  append((vmax - speed) / a, direction * a);
  append(cruise / vmax, 0.0);
  append(vmax / d, -direction * d);
}

void MotionAxis::start_move(SimTime now, double target, const MoveLimits& limits) {
  require_positive(limits.velocity, "move velocity");
  require_positive(limits.acceleration, "move acceleration");
  require_positive(limits.deceleration, "move deceleration");
  const State state = evaluate(now);
  restart(now, state);
  double position = state.position;
  double velocity = state.velocity;
  double distance = target - position;
  const double stopping = velocity * velocity / (2 * limits.deceleration);
  const bool away_or_overshoot =
      velocity * sign(distance) <= 0 || stopping > std::abs(distance) + kStoppingSlack;
  if (velocity != 0 && away_or_overshoot) {
    // Stop first, then travel back (or on) to the target from rest.
    const double t = std::abs(velocity) / limits.deceleration;
    append(t, -sign(velocity) * limits.deceleration);
    position += velocity * t / 2;
    velocity = 0;
    distance = target - position;
  }
  if (std::abs(distance) > kDistanceEpsilon) {
    plan_forward(sign(distance), std::abs(velocity), std::abs(distance), limits);
  }
  finish(true, target);
}

void MotionAxis::start_velocity(SimTime now, double velocity, double acceleration,
                                double deceleration) {
  require_positive(acceleration, "acceleration");
  require_positive(deceleration, "deceleration");
  const State state = evaluate(now);
  restart(now, state);
  double v = state.velocity;
  if (v != 0 && sign(velocity) != sign(v)) {
    append(std::abs(v) / deceleration, -sign(v) * deceleration);
    v = 0;
  }
  if (velocity != v) {
    const double rate = std::abs(velocity) > std::abs(v) ? acceleration : deceleration;
    append(std::abs(velocity - v) / rate, sign(velocity - v) * rate);
  }
  if (velocity != 0) append(kInfinity, 0.0);
  finish(false, 0.0);
}

void MotionAxis::abort(SimTime now, double deceleration) {
  require_positive(deceleration, "abort deceleration");
  const State state = evaluate(now);
  restart(now, state);
  if (state.velocity != 0) {
    append(std::abs(state.velocity) / deceleration, -sign(state.velocity) * deceleration);
  }
  finish(false, 0.0);
}

void MotionAxis::stop(SimTime now) {
  const double position = evaluate(now).position;
  restart(now, {position, 0.0, 0.0});
  finish(false, 0.0);
}

void MotionAxis::set_position(SimTime now, double position) {
  restart(now, {position, 0.0, 0.0});
  finish(false, 0.0);
}

void HomingSequence::start(MotionAxis& axis, SimTime now, double reference,
                           const MoveLimits& limits, double home_offset) {
  axis.start_move(now, reference, limits);
  home_offset_ = home_offset;
  phase_ = Phase::searching;
}

HomingSequence::Phase HomingSequence::update(MotionAxis& axis, SimTime now) {
  if (phase_ == Phase::searching && !axis.in_motion(now)) {
    axis.set_position(now, home_offset_);
    phase_ = Phase::succeeded;
  }
  return phase_;
}

void HomingSequence::fail() {
  if (phase_ == Phase::searching) phase_ = Phase::failed;
}

}  // namespace fieldgate::sim
