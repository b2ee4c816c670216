// Issue 12: replies carry no tag, so a reply that arrives after the reply timeout must never
// be taken as the answer to the next request. The reproduction, against the real
// daemon and the Copley simulator.
#include <gtest/gtest.h>

#include "copley_amplifiers.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

constexpr int kDesiredState = 0;  // holding 0: desired_state (0x24)
constexpr int kPosition = 0;      // input 0-1: motor_position
constexpr int kDeviceFailure = 0x04, kTargetFailed = 0x0B;

class CopleyLateReply : public PlantTest {
 protected:
  void SetUp() override {
    start(amplifier_plant());
    wait_inputs({1, 2, 3}, kPosition, 2);
  }
};

// reply_timeout 50 ms, the amplifiers answer in 70 ms: desired state 41 is no valid mode and
// the amplifier refuses it with e 14, so no write of it may ever be answered success.
TEST_F(CopleyLateReply, RefusedWritesAreNeverConfirmedByALateReply) {
  plant_->sim().send_line("delay 70");
  int successes = 0;
  for (int i = 0; i < 20; ++i) {
    const auto other = client_->write_single(2, kDesiredState, 0);
    EXPECT_NE(other.exception, -1);
    const auto refused = client_->write_single(1, kDesiredState, 41);
    if (refused.ok()) ++successes;
    EXPECT_TRUE(refused.exception == kTargetFailed || refused.exception == kDeviceFailure)
        << "round " << i << ": exception " << refused.exception;
  }
  EXPECT_EQ(successes, 0);
  // The late replies were drained, counted and logged, not used: a write either timed out
  // (outcome unknown) and the proof of alignment that followed read its late reply as a stray
  // one, or it was refused at the gateway because no proof passed ("line not in step").
  const std::string log = plant_->daemon().log();
  EXPECT_NE(log.find("drained"), std::string::npos);
  EXPECT_TRUE(log.find("outcome unknown") != std::string::npos ||
              log.find("cannot prove the line in step") != std::string::npos)
      << log;
}

// The same sequence while the amplifiers answer within the timeout: refusals are reported as
// the device's refusal (e 14). A reply the loaded test machine delays past the timeout may
// still turn one into 0x0B, never into success.
TEST_F(CopleyLateReply, RefusalsWithinTheTimeoutAreReportedAsSuch) {
  plant_->sim().send_line("delay 20");
  int refusals = 0;
  for (int i = 0; i < 10; ++i) {
    const auto other = client_->write_single(2, kDesiredState, 0);
    EXPECT_TRUE(other.ok() || other.exception == kTargetFailed) << "round " << i;
    const auto refused = client_->write_single(1, kDesiredState, 41);
    EXPECT_TRUE(refused.exception == kDeviceFailure || refused.exception == kTargetFailed)
        << "round " << i << ": exception " << refused.exception;
    if (refused.exception == kDeviceFailure) ++refusals;
  }
  EXPECT_GE(refusals, 5);
}

// After the delay ends, the nodes come back and serve their own values again.
TEST_F(CopleyLateReply, NodesRecoverOnceRepliesAreInTimeAgain) {
  plant_->sim().send_line("delay 70");
  for (int i = 0; i < 5; ++i) EXPECT_FALSE(client_->write_single(1, kDesiredState, 41).ok());
  plant_->sim().send_line("delay 0");
  for (int unit : {1, 2, 3})
    ASSERT_TRUE(wait_until([&] { return client_->read_input(unit, kPosition, 2).ok(); }, 20s))
        << "unit " << unit;
  EXPECT_EQ(client_->write_single(1, kDesiredState, 41).exception, kDeviceFailure);
  EXPECT_TRUE(client_->write_single(1, kDesiredState, 0).ok());
}

}  // namespace
}  // namespace fieldgate::test
