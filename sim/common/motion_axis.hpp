#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "sim/common/wire_pacing.hpp"

namespace fieldgate::sim {

// Rate limits of a point-to-point move, in counts, counts/s and counts/s^2. All positive.
struct MoveLimits {
  double velocity;
  double acceleration;
  double deceleration;
};

// One simulated axis: a trajectory made of constant-acceleration segments, evaluated at the
// time the caller passes in. Nothing here reads a clock, so tests drive it with literal times.
//
// Every command starts from the axis state at `now`, so moves can be updated in flight, reversed
// or aborted. The trajectory is the commanded motion; simulators that want a following error
// derive the actual position from it.
class MotionAxis {
 public:
  explicit MotionAxis(double position = 0.0) : start_position_(position), rest_(position) {}

  double position(SimTime now) const { return evaluate(now).position; }
  double velocity(SimTime now) const { return evaluate(now).velocity; }
  double acceleration(SimTime now) const { return evaluate(now).acceleration; }
  // Rounded to whole counts, the way drives report positions.
  std::int64_t position_counts(SimTime now) const;
  bool in_motion(SimTime now) const;
  // Where the current trajectory comes to rest; during a velocity move (which has no end) the
  // position at `now`.
  double rest_position(SimTime now) const;
  bool velocity_move() const { return endless_; }

  // Trapezoidal move to `target`. Starting while moving blends from the current velocity: if the
  // axis cannot stop before the target (or moves away from it) it first decelerates to a stop.
  void start_move(SimTime now, double target, const MoveLimits& limits);
  // Ramps to `velocity` (signed, counts/s) and holds it until the next command. Speeding up
  // uses `acceleration`, slowing down (or reversing through zero) uses `deceleration`.
  void start_velocity(SimTime now, double velocity, double acceleration, double deceleration);
  // Decelerates to a stop at `deceleration`.
  void abort(SimTime now, double deceleration);
  // Stops dead (drive disabled, fault): the position freezes where it is.
  void stop(SimTime now);
  // Redefines the coordinate system; the axis is at rest afterwards.
  void set_position(SimTime now, double position);

 private:
  struct Segment {
    double duration;  // seconds; infinity for a cruise that lasts until the next command
    double acceleration;
  };
  struct State {
    double position;
    double velocity;
    double acceleration;
  };

  State evaluate(SimTime now) const;
  void restart(SimTime now, State from);
  void append(double duration, double acceleration);
  void plan_forward(double direction, double speed, double distance, const MoveLimits& limits);
  void finish(bool snap_to_target, double target);

  SimTime start_time_{};
  double start_position_;
  double start_velocity_ = 0.0;
  std::vector<Segment> segments_;
  double duration_ = 0.0;  // sum of finite segment durations
  bool endless_ = false;
  double rest_;
};

// The simplest homing sequence a simulated drive needs: travel to where the home reference is,
// then declare that spot to be `home_offset` and report success.
class HomingSequence {
 public:
  enum class Phase { idle, searching, succeeded, failed };

  // Moves toward `reference` (absolute, in the axis' current coordinates).
  void start(MotionAxis& axis, SimTime now, double reference, const MoveLimits& limits,
             double home_offset);
  // Completes the sequence once the axis has arrived; call before every look at the axis.
  Phase update(MotionAxis& axis, SimTime now);
  // Ends a search that has not finished (abort, disable, fault) as failed.
  void fail();
  // Forgets the last result (reset).
  void clear() { phase_ = Phase::idle; }

  Phase phase() const { return phase_; }
  bool searching() const { return phase_ == Phase::searching; }

 private:
  Phase phase_ = Phase::idle;
  double home_offset_ = 0.0;
};

}  // namespace fieldgate::sim
