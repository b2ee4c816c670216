// The chain shadow: pacing above 10,000 steps/s (manual p.14), the motion guard (§6, §8.3),
// the EEPROM guard (§5, §8.10) and the outputs rule (§3 `A`).
#include <gtest/gtest.h>

#include "drivers/ims_party_line/ims_chain.hpp"

namespace fieldgate::ims {
namespace {

using namespace std::chrono_literals;
const ChainShadow::Clock::time_point t0 = ChainShadow::Clock::time_point{} + 1000h;

TEST(ImsChainShadow, FastSlewPacesTheChainUntilTheAxisIsIdle) {
  ChainShadow s;
  EXPECT_FALSE(s.fast());
  s.acknowledged('A', "V15000", t0);
  EXPECT_FALSE(s.fast()) << "a parameter alone moves nothing";
  s.acknowledged('A', "R20000", t0);
  EXPECT_TRUE(s.fast());
  EXPECT_DOUBLE_EQ(s.step_rate('A'), 15000);
  s.acknowledged('B', "^", t0, 0);  // another axis idle changes nothing
  EXPECT_TRUE(s.fast());
  s.acknowledged('A', "^", t0, 33);  // moving + ramping
  EXPECT_TRUE(s.fast());
  s.acknowledged('A', "^", t0, 0);
  EXPECT_FALSE(s.fast());
}

TEST(ImsChainShadow, SlowMovesAndUnknownSlewDoNotPace) {
  ChainShadow s;
  s.acknowledged('A', "R20000", t0);  // V never sent: the unit's saved value is unknown
  EXPECT_FALSE(s.fast());
  s.acknowledged('A', "V 9000", t0);
  s.acknowledged('A', "+500", t0);
  EXPECT_FALSE(s.fast());
}

TEST(ImsChainShadow, VelocityAndHomeSpeeds) {
  ChainShadow s;
  s.acknowledged('A', "M-12000", t0);
  EXPECT_TRUE(s.fast());
  s.acknowledged('A', "M0", t0);
  EXPECT_TRUE(s.fast()) << "M0 ramps down from the current speed";
  s.acknowledged('A', "^", t0, 0);
  EXPECT_FALSE(s.fast());
  s.acknowledged('B', "F12000 1", t0);
  EXPECT_TRUE(s.fast());
  s.global("\x1b", t0);  // ESC stops every axis at once
  EXPECT_FALSE(s.fast());
  EXPECT_FALSE(s.moving('B'));
}

TEST(ImsChainShadow, ResetForgetsTheSlew) {
  ChainShadow s;
  s.acknowledged('A', "V15000", t0);
  s.global("\x03", t0);
  s.acknowledged('A', "R1000", t0);
  EXPECT_FALSE(s.fast());
  s.acknowledged('A', "V15000", t0);
  s.acknowledged('A', "C0", t0);  // reloads the saved parameters too
  s.acknowledged('A', "R1000", t0);
  EXPECT_FALSE(s.fast());
}

TEST(ImsChainShadow, GlobalCommandsApplyToEveryKnownUnit) {
  ChainShadow s;
  s.acknowledged('A', "^", t0, 0);
  s.acknowledged('B', "^", t0, 0);
  s.global("M15000", t0);  // sent as *M15000
  EXPECT_TRUE(s.moving('A'));
  EXPECT_TRUE(s.moving('B'));
  EXPECT_TRUE(s.fast());
  s.global("@", t0);  // soft stop: decelerating, still moving until `^` says so
  EXPECT_TRUE(s.moving('A'));
}

TEST(ImsChainShadow, SecondIndexWhileMovingIsRefused) {
  ChainShadow s;
  s.acknowledged('A', "^", t0, 0);
  EXPECT_FALSE(s.check('A', "R1000", t0));
  s.acknowledged('A', "R1000", t0);
  auto refusal = s.check('A', "R0", t0);
  ASSERT_TRUE(refusal);
  EXPECT_EQ(refusal->code, Refusal::axis_moving);
  EXPECT_NE(refusal->text.find("queue"), std::string::npos) << refusal->text;
  for (const char* c : {"+5", "-5", "F500 0", "G100", "O", "o"})
    EXPECT_TRUE(s.check('A', c, t0)) << c;
  // Parameters, queries, jog speed changes and the other axes go on.
  for (const char* c : {"Z", "^", "V3000", "M2000", "M0", "A8"})
    EXPECT_FALSE(s.check('A', c, t0)) << c;
  EXPECT_FALSE(s.check('B', "R5", t0));
  s.acknowledged('A', "^", t0, 1);
  EXPECT_TRUE(s.check('A', "R0", t0));
  s.acknowledged('A', "^", t0, 0);
  EXPECT_FALSE(s.check('A', "R0", t0));
}

TEST(ImsChainShadow, WithoutStatusPollsTheGuardCannotClearSoItStaysOff) {
  ChainShadow s;
  s.acknowledged('A', "R1000", t0);
  EXPECT_FALSE(s.check('A', "R0", t0));
}

TEST(ImsChainShadow, SavesAreRateLimitedPerUnit) {
  ChainShadow s;
  EXPECT_FALSE(s.check('A', "S", t0));
  s.acknowledged('A', "S", t0);
  auto refusal = s.check('A', "S", t0 + 10s);
  ASSERT_TRUE(refusal);
  EXPECT_EQ(refusal->code, Refusal::eeprom_rate);
  EXPECT_NE(refusal->text.find("10 s ago"), std::string::npos) << refusal->text;
  EXPECT_FALSE(s.check('B', "S", t0 + 10s));
  EXPECT_FALSE(s.check('A', "S", t0 + ChainShadow::kSaveInterval));
}

TEST(ImsChainShadow, OutputsAreWrittenAsMultiplesOfEight) {
  ChainShadow s;
  for (const char* ok : {"A0", "A8", "A 48", "A56", "A", "A129"})
    EXPECT_FALSE(s.check('A', ok, t0)) << ok;
  for (const char* bad : {"A12", "A64", "A-8", "A7"}) {
    auto refusal = s.check('A', bad, t0);
    ASSERT_TRUE(refusal) << bad;
    EXPECT_EQ(refusal->code, Refusal::output_value);
  }
}

TEST(ImsChainShadow, LinesWithTerminatorsAreRefused) {
  ChainShadow s;
  for (const char* bad : {"", "Z\n", "Z\r", "\rZ", "\x1b", "V1\x03"}) {
    auto refusal = s.check('A', bad, t0);
    ASSERT_TRUE(refusal) << bad;
    EXPECT_EQ(refusal->code, Refusal::invalid_line);
  }
}

}  // namespace
}  // namespace fieldgate::ims
