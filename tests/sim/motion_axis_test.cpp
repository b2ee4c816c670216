#include "sim/common/motion_axis.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "tests/sim/sim_time.hpp"

namespace fieldgate::sim {
namespace {

using test::at;

// 0 -> 10000 at 1000 counts/s, accelerating at 1000 and braking at 2000 counts/s^2:
// 1 s / 500 counts up, 9.25 s cruise, 0.5 s / 250 counts down; 10.75 s in all.
TEST(MotionAxis, TrapezoidWithCruise) {
  MotionAxis axis;
  axis.start_move(at(0), 10000, {1000, 1000, 2000});
  EXPECT_DOUBLE_EQ(axis.position(at(0)), 0);
  EXPECT_NEAR(axis.position(at(0.5)), 125, 1e-6);
  EXPECT_NEAR(axis.velocity(at(0.5)), 500, 1e-6);
  EXPECT_NEAR(axis.acceleration(at(0.5)), 1000, 1e-6);
  EXPECT_NEAR(axis.position(at(1)), 500, 1e-6);
  EXPECT_NEAR(axis.position(at(5)), 4500, 1e-6);
  EXPECT_NEAR(axis.velocity(at(5)), 1000, 1e-6);
  EXPECT_NEAR(axis.acceleration(at(5)), 0, 1e-6);
  EXPECT_NEAR(axis.position(at(10.5)), 10000 - 62.5, 1e-6);
  EXPECT_NEAR(axis.acceleration(at(10.5)), -2000, 1e-6);
  EXPECT_TRUE(axis.in_motion(at(10.74)));
  EXPECT_FALSE(axis.in_motion(at(10.76)));
  EXPECT_EQ(axis.position(at(11)), 10000);
  EXPECT_EQ(axis.velocity(at(11)), 0);
  EXPECT_EQ(axis.position_counts(at(11)), 10000);
  EXPECT_EQ(axis.rest_position(at(3)), 10000);
}

TEST(MotionAxis, TriangleWhenTheMoveIsTooShortToCruise) {
  MotionAxis axis(50);
  axis.start_move(at(0), -50, {1000, 1000, 1000});
  // Peak speed sqrt(a * d) = sqrt(1000 * 50) reached halfway, after sqrt(0.1) s.
  const double half = std::sqrt(0.1);
  EXPECT_NEAR(axis.position(at(half)), 0, 1e-6);
  EXPECT_NEAR(axis.velocity(at(half)), -std::sqrt(1000.0 * 100.0), 1e-6);
  EXPECT_TRUE(axis.in_motion(at(2 * half - 0.001)));
  EXPECT_FALSE(axis.in_motion(at(2 * half + 0.001)));
  EXPECT_EQ(axis.position(at(1)), -50);
}

TEST(MotionAxis, ExtendingAMoveInFlightKeepsTheVelocity) {
  MotionAxis axis;
  axis.start_move(at(0), 10000, {1000, 1000, 1000});
  axis.start_move(at(5), 20000, {1000, 1000, 1000});
  EXPECT_NEAR(axis.velocity(at(5.001)), 1000, 1e-6);
  EXPECT_NEAR(axis.position(at(15)), 14500, 1e-6);
  EXPECT_EQ(axis.position(at(30)), 20000);
}

TEST(MotionAxis, ShorteningAMoveBehindTheAxisStopsThenReturns) {
  MotionAxis axis;
  axis.start_move(at(0), 10000, {1000, 1000, 1000});
  axis.start_move(at(5), 2000, {1000, 1000, 1000});  // now at 4500, moving +1000
  EXPECT_NEAR(axis.velocity(at(5.5)), 500, 1e-6);    // braking, not reversing yet
  EXPECT_NEAR(axis.position(at(6)), 5000, 1e-6);     // stopped 500 counts further
  EXPECT_LT(axis.velocity(at(7)), 0);
  EXPECT_TRUE(axis.in_motion(at(9)));
  EXPECT_EQ(axis.position(at(20)), 2000);
  EXPECT_FALSE(axis.in_motion(at(20)));
}

TEST(MotionAxis, ReissuingTheTargetWhileBrakingDoesNotOvershoot) {
  MotionAxis axis;
  const MoveLimits limits{1000, 1000, 1000};
  axis.start_move(at(0), 1500, limits);  // 1 s up, 0.5 s cruise, 1 s down
  axis.start_move(at(2), 1500, limits);
  for (double t = 2; t < 3.5; t += 0.01) EXPECT_LE(axis.position(at(t)), 1500 + 1e-6) << t;
  EXPECT_FALSE(axis.in_motion(at(2.6)));
  EXPECT_EQ(axis.position(at(2.6)), 1500);
}

TEST(MotionAxis, VelocityMoveRunsUntilTheNextCommand) {
  MotionAxis axis;
  axis.start_velocity(at(0), 500, 1000, 2000);
  EXPECT_NEAR(axis.velocity(at(0.25)), 250, 1e-6);
  EXPECT_NEAR(axis.position(at(2)), 125 + 750, 1e-6);
  EXPECT_TRUE(axis.in_motion(at(1000)));
  EXPECT_TRUE(axis.velocity_move());
  // Reverse: brake at 2000 (0.25 s), then accelerate at 1000 (0.5 s).
  axis.start_velocity(at(2), -500, 1000, 2000);
  EXPECT_NEAR(axis.velocity(at(2.25)), 0, 1e-6);
  EXPECT_NEAR(axis.velocity(at(2.5)), -250, 1e-6);
  EXPECT_NEAR(axis.velocity(at(3)), -500, 1e-6);
  axis.start_velocity(at(4), 0, 1000, 2000);
  EXPECT_FALSE(axis.in_motion(at(4.3)));
  EXPECT_FALSE(axis.velocity_move());
}

TEST(MotionAxis, AbortBrakesAtTheGivenRate) {
  MotionAxis axis;
  axis.start_move(at(0), 100000, {1000, 1000, 1000});
  axis.abort(at(5), 4000);  // at 4500 counts, 1000 counts/s: 0.25 s and 125 counts to stop
  EXPECT_TRUE(axis.in_motion(at(5.2)));
  EXPECT_FALSE(axis.in_motion(at(5.26)));
  EXPECT_NEAR(axis.position(at(6)), 4625, 1e-6);
  EXPECT_NEAR(axis.rest_position(at(5.1)), 4625, 1e-6);
}

TEST(MotionAxis, StopFreezesAndSetPositionRedefines) {
  MotionAxis axis;
  axis.start_move(at(0), 10000, {1000, 1000, 1000});
  axis.stop(at(1));
  EXPECT_NEAR(axis.position(at(2)), 500, 1e-6);
  EXPECT_FALSE(axis.in_motion(at(1)));
  axis.set_position(at(3), -7);
  EXPECT_EQ(axis.position_counts(at(4)), -7);
}

TEST(MotionAxis, RejectsRatesThatCannotMove) {
  MotionAxis axis;
  EXPECT_THROW(axis.start_move(at(0), 10, {0, 1, 1}), std::invalid_argument);
  EXPECT_THROW(axis.start_move(at(0), 10, {1, 0, 1}), std::invalid_argument);
  EXPECT_THROW(axis.start_move(at(0), 10, {1, 1, -1}), std::invalid_argument);
  EXPECT_THROW(axis.abort(at(0), 0), std::invalid_argument);
}

TEST(MotionAxis, MoveToTheCurrentPositionDoesNothing) {
  MotionAxis axis(42);
  axis.start_move(at(0), 42, {1000, 1000, 1000});
  EXPECT_FALSE(axis.in_motion(at(0)));
  EXPECT_EQ(axis.position(at(1)), 42);
}

TEST(HomingSequence, TravelsToTheReferenceThenTakesTheOffset) {
  MotionAxis axis(300);
  HomingSequence homing;
  homing.start(axis, at(0), 1300, {1000, 10000, 10000}, 500);
  EXPECT_EQ(homing.update(axis, at(0.5)), HomingSequence::Phase::searching);
  EXPECT_TRUE(axis.in_motion(at(0.5)));
  EXPECT_EQ(homing.update(axis, at(2)), HomingSequence::Phase::succeeded);
  EXPECT_EQ(axis.position_counts(at(2)), 500);
  EXPECT_FALSE(axis.in_motion(at(2)));
}

TEST(HomingSequence, FailsWhenInterrupted) {
  MotionAxis axis;
  HomingSequence homing;
  homing.start(axis, at(0), 1000, {1000, 10000, 10000}, 0);
  axis.abort(at(0.5), 10000);
  homing.fail();
  EXPECT_EQ(homing.update(axis, at(5)), HomingSequence::Phase::failed);
  EXPECT_NEAR(axis.position(at(5)), 500, 1e-6);  // 450 counts out, 50 more to stop
}

}  // namespace
}  // namespace fieldgate::sim
