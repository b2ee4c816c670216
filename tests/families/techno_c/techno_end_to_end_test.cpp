// The real daemon against fieldgate-sim-techno on PTYs, through Modbus TCP (libmodbus): a C142
// with capital-letter moves (the handshake at the end of the motion, the write confirmed early)
// and an IT116G with lower-case moves (completion from position polls).
#include <gtest/gtest.h>

#include <regex>
#include <thread>

#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// config/models/techno-c142.yaml, in declaration order.
constexpr int kPositionX = 0, kPositionY = 2, kPositionZ = 4, kInMotion = 6, kPositionXmm = 7;
constexpr int kPlane = 0, kOutputs1 = 1;
constexpr int kMoving = 0;  // discrete input
constexpr int kCommand = 100, kStatus = 101, kError = 102;
constexpr int kTargetX = 110, kTargetY = 112, kTargetZ = 114, kDistanceX = 116;
constexpr int kSpeedX = 122, kHomeAxes = 125, kHomeSpeedX = 127;
constexpr int kInitialise = 1, kHome = 2, kMoveAbsolute = 3, kMoveRelative = 4, kStop = 5,
              kSetHomeSpeeds = 7, kClearFault = 9;
// config/models/techno-it116g.yaml
constexpr int kItPosition = 0, kItInMotion = 2, kItPositionIn = 3;
constexpr int kItTarget = 110, kItSpeed = 114;

constexpr int kIllegalValue = 0x03, kDeviceFailure = 0x04, kServerBusy = 0x06;
constexpr int kDiagOnline = 1000;
constexpr int kC142 = 1, kIt116g = 2;

class TechnoEndToEnd : public PlantTest {
 protected:
  void SetUp() override {
    // Not the 50 ms a controller needs: on a loaded host (eight tests on two cores) the Whedco
    // and Copley simulators answered 80-220 ms late, and a CI run failed a test here (its output
    // was not kept). The gateway's own stalls are covered by what the OS buffers.
    const std::string timing =
        "reply_timeout: 200ms, byte_timeout: 30ms, retries: 1, offline_after: 3, "
        "probe_interval: 300ms";
    start({{"techno-c142",
            "techno-c",
            // Power-up state (axes undefined): the family initialises at first contact.
            {FIELDGATE_SIM_TECHNO, "--link", "{link}", "--variant", "c142", "--verbose"},
            "baud: 19200",
            timing,
            "      - {name: c142, address: 0, model: techno-c142, unit_id: 1}\n"},
           {"techno-it116g",
            "techno-c",
            {FIELDGATE_SIM_TECHNO, "--link", "{link}", "--variant", "it116g"},
            "baud: 9600",
            timing,
            "      - {name: it116g, address: 0, model: techno-it116g, unit_id: 2}\n"}});
    wait_inputs({kC142, kIt116g}, 0, 2);
  }

  std::optional<int32_t> input32(int unit, int address) {
    return client_->read_input_i32(unit, address);
  }
  // A control command to simulator i; returns its reply line.
  std::string control(std::size_t i, const std::string& line) {
    const std::string verb = line.substr(0, line.find(' '));
    const std::regex reply("(ok|error:) " + verb + "[^\n]*");
    auto count = [&] {
      const std::string log = plant_->sim(i).log();
      return std::distance(std::sregex_iterator(log.begin(), log.end(), reply),
                           std::sregex_iterator());
    };
    const auto before = count();
    plant_->sim(i).send_line(line);
    EXPECT_TRUE(wait_until([&] { return count() > before; }, 5s)) << line;
    const std::string log = plant_->sim(i).log();
    std::string last;
    for (auto it = std::sregex_iterator(log.begin(), log.end(), reply);
         it != std::sregex_iterator(); ++it)
      last = it->str();
    return last;
  }
  long sim_counter(std::size_t i, const std::string& name) {
    const std::string line = control(i, "counters");
    const std::smatch m = [&] {
      std::smatch match;
      std::regex_search(line, match, std::regex(name + "=([0-9]+)"));
      return match;
    }();
    return m.empty() ? -1 : std::stol(m[1]);
  }
};

TEST_F(TechnoEndToEnd, ThreeAxisMoveItsCompletionSeenByThePlc) {
  ASSERT_TRUE(client_->write_i32(kC142, kTargetX, 4000).ok());
  ASSERT_TRUE(client_->write_i32(kC142, kTargetY, 3000).ok());
  ASSERT_TRUE(client_->write_i32(kC142, kTargetZ, 1000).ok());
  const auto t0 = Clock::now();
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kMoveAbsolute).ok());
  const auto confirmed = Clock::now() - t0;
  // Confirmed once the capital M had been on its way for confirm_after (300 ms) without an
  // error, long before the ~2.6 s motion ends; the action is busy meanwhile.
  EXPECT_GE(confirmed, 250ms);
  EXPECT_LT(confirmed, 2500ms);
  EXPECT_EQ(holding(kC142, kStatus), 1);
  ASSERT_TRUE(wait_until([&] { return holding(kC142, kStatus) == 2; }, 15s));
  EXPECT_GE(Clock::now() - t0, 2500ms);
  EXPECT_EQ(input32(kC142, kPositionX), 4000);
  EXPECT_EQ(input32(kC142, kPositionY), 3000);
  EXPECT_EQ(input32(kC142, kPositionZ), 1000);
  EXPECT_EQ(input32(kC142, kPositionXmm), 4000);  // 40.00 mm at 100 steps/mm, 0.01 mm counts
  auto moving = client_->read_discrete(kC142, kMoving, 1);
  ASSERT_TRUE(moving.ok());
  EXPECT_EQ(moving.values[0], 0);
  EXPECT_EQ(holding(kC142, kError), 0);
  const std::string sim_log = plant_->sim(0).log();
  EXPECT_NE(sim_log.find("rx \"@0M4000,2000,3000,2000,1000,2000,1000,2000\\r\""), std::string::npos)
      << sim_log;
}

TEST_F(TechnoEndToEnd, PowerUpStateIsInitialisedAtFirstContactAndLogged) {
  const std::string log = plant_->daemon().log();
  EXPECT_NE(log.find("sent the axes definition '7'"), std::string::npos) << log;
  EXPECT_NE(log.find("sent the axes definition '1'"), std::string::npos) << log;
}

// C142 against an independent implementation: a write during a capital move held its Modbus
// reply until the move ended, and `moving` read 0. Now: 0x06 at once, `moving` 1, stop still
// gets through.
TEST_F(TechnoEndToEnd, WritesDuringACapitalMoveAnswerBusyAtOnce) {
  ASSERT_TRUE(client_->write_single(kC142, kSpeedX, 2000).ok());
  ASSERT_TRUE(client_->write_i32(kC142, kTargetX, 12000).ok());  // 6 s
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kMoveAbsolute).ok());
  EXPECT_EQ(holding(kC142, kStatus), 1);
  auto moving = client_->read_discrete(kC142, kMoving, 1);
  ASSERT_TRUE(moving.ok());
  EXPECT_EQ(moving.values[0], 1);
  auto t0 = Clock::now();
  EXPECT_EQ(client_->write_single(kC142, kPlane, 1).exception, kServerBusy);
  EXPECT_LT(Clock::now() - t0, 1s);
  t0 = Clock::now();
  EXPECT_EQ(client_->write_single(kC142, kCommand, kMoveRelative).exception, kServerBusy);
  EXPECT_LT(Clock::now() - t0, 1s);
  // Setpoints touch no wire: stored at once.
  EXPECT_TRUE(client_->write_i32(kC142, kDistanceX, 50).ok());
  EXPECT_EQ(holding(kC142, kStatus), 1);
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kStop).ok());
  ASSERT_TRUE(wait_until([&] { return holding(kC142, kStatus) == 2; }, 10s));
  EXPECT_TRUE(client_->write_single(kC142, kPlane, 0).ok());
}

TEST_F(TechnoEndToEnd, StopDuringALongMove) {
  ASSERT_TRUE(client_->write_single(kC142, kSpeedX, 1000).ok());
  ASSERT_TRUE(client_->write_i32(kC142, kTargetX, 90000).ok());  // 90 s at 1000 steps/s
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kMoveAbsolute).ok());
  std::this_thread::sleep_for(1s);
  EXPECT_EQ(holding(kC142, kStatus), 1);
  const auto t0 = Clock::now();
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kStop).ok());
  EXPECT_LT(Clock::now() - t0, 5s);  // the stop did not wait for the 90 s move's line
  ASSERT_TRUE(wait_until(
      [&] { return holding(kC142, kCommand) == kStop && holding(kC142, kStatus) == 2; }, 10s));
  const auto x = input32(kC142, kPositionX);
  ASSERT_TRUE(x);
  EXPECT_GT(*x, 500);
  EXPECT_LT(*x, 5000);
  EXPECT_NE(control(0, "state").find("busy=idle"), std::string::npos);
  EXPECT_EQ(sim_counter(0, "stops"), 2);
  // The controller takes the next move.
  ASSERT_TRUE(client_->write_i32(kC142, kDistanceX, 100).ok());
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kMoveRelative).ok());
  ASSERT_TRUE(wait_until([&] { return holding(kC142, kStatus) == 2; }, 10s));
  EXPECT_EQ(input32(kC142, kPositionX), *x + 100);
}

TEST_F(TechnoEndToEnd, InvalidWritesAreRejectedWith03AndNothingIsSent) {
  std::this_thread::sleep_for(200ms);
  const long commands = sim_counter(0, "commands");
  ASSERT_GE(commands, 0);
  // Axis masks beyond X=1 Y=2 Z=4, speeds outside 30..10000, positions beyond ±8,000,000, a
  // plane or output byte out of range, an action code the model does not have.
  EXPECT_EQ(client_->write_single(kC142, kHomeAxes, 8).exception, kIllegalValue);
  EXPECT_EQ(client_->write_single(kC142, kHomeAxes, 0).exception, kIllegalValue);
  EXPECT_EQ(client_->write_single(kC142, kSpeedX, 20).exception, kIllegalValue);
  EXPECT_EQ(client_->write_single(kC142, kSpeedX, 10001).exception, kIllegalValue);
  EXPECT_EQ(client_->write_single(kC142, kHomeSpeedX, 5000).exception, kIllegalValue);
  EXPECT_EQ(client_->write_i32(kC142, kTargetX, 8000001).exception, kIllegalValue);
  EXPECT_EQ(client_->write_single(kC142, kPlane, 3).exception, kIllegalValue);
  EXPECT_EQ(client_->write_single(kC142, kOutputs1, 256).exception, kIllegalValue);
  EXPECT_EQ(client_->write_single(kC142, kCommand, 99).exception, kIllegalValue);
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(sim_counter(0, "commands"), commands);  // only position polls reached the line
  EXPECT_EQ(holding(kC142, kHomeAxes), 7);          // the setpoint kept its value
  // A valid write of the same registers goes through.
  ASSERT_TRUE(client_->write_single(kC142, kOutputs1, 205).ok());
  EXPECT_EQ(sim_counter(0, "commands"), commands + 1);
  EXPECT_NE(control(0, "state").find("outputs=205,0"), std::string::npos);
  EXPECT_EQ(holding(kC142, kOutputs1), 205);  // a write-only point reads back its confirmed write
}

TEST_F(TechnoEndToEnd, HomingThatNeverAnswersBecomesATimeoutFaultThePlcCanReadAndClear) {
  EXPECT_EQ(control(0, "mechanics off"), "ok mechanics off");
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(client_->write_single(kC142, kHomeSpeedX + i, 4999).ok());
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kSetHomeSpeeds).ok());
  EXPECT_EQ(holding(kC142, kStatus), 2);
  ASSERT_TRUE(client_->write_single(kC142, kHomeAxes, 1).ok());
  const auto t0 = Clock::now();
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kHome).ok());
  EXPECT_EQ(holding(kC142, kStatus), 1);
  // travel 20000 steps at 4999 steps/s, x1.25 + 1 s: about 6 s until the family gives up.
  ASSERT_TRUE(wait_until([&] { return holding(kC142, kStatus) == 3; }, 20s));
  EXPECT_GE(Clock::now() - t0, 5s);
  EXPECT_EQ(holding(kC142, kError), 0xfffc);  // no reply: the outcome is unknown
  // The family sent STOP twice, which is what ends the homing loop (manual p.41).
  EXPECT_EQ(sim_counter(0, "stops"), 2);
  EXPECT_TRUE(
      wait_until([&] { return control(0, "state").find("busy=idle") != std::string::npos; }, 2s));
  // The node stays online and polled.
  ASSERT_TRUE(wait_until([&] { return client_->read_input(kC142, kPositionX, 2).ok(); }));
  EXPECT_EQ(client_->read_input(kC142, kDiagOnline, 1).values, std::vector<uint16_t>{1});
  // Clear the fault.
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kClearFault).ok());
  EXPECT_EQ(holding(kC142, kStatus), 2);
  EXPECT_EQ(holding(kC142, kError), 0);
  // With the mechanics back, homing completes and X reads 0.
  EXPECT_EQ(control(0, "mechanics on"), "ok mechanics on");
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kHome).ok());
  ASSERT_TRUE(wait_until([&] { return holding(kC142, kStatus) == 2; }, 30s));
  EXPECT_EQ(input32(kC142, kPositionX), 0);
  const std::string log = plant_->daemon().log();
  EXPECT_NE(log.find("homing run without mechanics never answers"), std::string::npos) << log;
}

TEST_F(TechnoEndToEnd, ErrorHandshakeAnswersTheWriteWith04) {
  // Behind the home switch (the simulator starts 5000 steps from it): the controller answers
  // 2 at once, before confirm_after, so the write gets 0x04 and the code.
  ASSERT_TRUE(client_->write_i32(kC142, kTargetX, -10000).ok());
  EXPECT_EQ(client_->write_single(kC142, kCommand, kMoveAbsolute).exception, kDeviceFailure);
  EXPECT_EQ(holding(kC142, kStatus), 3);
  EXPECT_EQ(holding(kC142, kError), '2');
  // Power-cycled controller: the next poll answers 4 (axis not defined); the family sends the
  // axes definition again and logs it.
  EXPECT_EQ(control(0, "power-cycle"), "ok power-cycle");
  ASSERT_TRUE(wait_until([&] {
    return plant_->daemon().log().find("lost its definition") != std::string::npos;
  })) << plant_->daemon().log();
  ASSERT_TRUE(client_->write_i32(kC142, kTargetX, 10).ok());
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kMoveAbsolute).ok());
  ASSERT_TRUE(wait_until([&] { return holding(kC142, kStatus) == 2; }, 10s));
  EXPECT_EQ(input32(kC142, kPositionX), 10);
}

// IT116G against an independent implementation: the limit stops the axis at 3424 of 4424 and
// the controller sends `2` after the `0` of the start. The action fails with that code.
TEST_F(TechnoEndToEnd, LimitDuringALowerCaseMoveFailsTheActionWithItsCode) {
  // Machine coordinates: the axis starts 5000 steps from its home switch, where P reads 0.
  EXPECT_EQ(control(1, "limit 8424"), "ok limit 8424");
  ASSERT_TRUE(client_->write_i32(kIt116g, kItTarget, 4424).ok());
  ASSERT_TRUE(client_->write_single(kIt116g, kItSpeed, 2000).ok());
  ASSERT_TRUE(client_->write_single(kIt116g, kCommand, kMoveAbsolute).ok());
  ASSERT_TRUE(wait_until([&] { return holding(kIt116g, kStatus) != 1; }, 15s));
  EXPECT_EQ(holding(kIt116g, kStatus), 3);
  EXPECT_EQ(holding(kIt116g, kError), '2');
  EXPECT_EQ(input32(kIt116g, kItPosition), 3424);
}

// A corrupted end-of-move handshake is not a timeout: its own action error code.
TEST_F(TechnoEndToEnd, CorruptedEndOfMoveReplyHasItsOwnErrorCode) {
  ASSERT_TRUE(client_->write_i32(kC142, kTargetX, 3000).ok());
  ASSERT_TRUE(client_->write_single(kC142, kCommand, kMoveAbsolute).ok());
  EXPECT_EQ(control(0, "garbage 1"), "ok garbage 1");
  ASSERT_TRUE(wait_until([&] { return holding(kC142, kStatus) != 1; }, 15s));
  EXPECT_EQ(holding(kC142, kStatus), 3);
  EXPECT_EQ(holding(kC142, kError), 0xfffb);
}

TEST_F(TechnoEndToEnd, LowerCaseMoveOnTheIt116gCompletesFromPolls) {
  ASSERT_TRUE(client_->write_i32(kIt116g, kItTarget, 3000).ok());
  ASSERT_TRUE(client_->write_single(kIt116g, kItSpeed, 2000).ok());
  const auto t0 = Clock::now();
  ASSERT_TRUE(client_->write_single(kIt116g, kCommand, kMoveAbsolute).ok());
  EXPECT_LT(Clock::now() - t0, 1000ms);  // m answers at the start of the 1.5 s motion
  EXPECT_EQ(holding(kIt116g, kStatus), 1);
  // Positions are live while it moves (the line is free).
  bool saw_motion = false;
  ASSERT_TRUE(wait_until(
      [&] {
        const auto p = input32(kIt116g, kItPosition);
        auto m = client_->read_input(kIt116g, kItInMotion, 1);
        if (p && m.ok() && m.values[0] == 1 && *p > 0 && *p < 3000) saw_motion = true;
        return holding(kIt116g, kStatus) == 2;
      },
      15s));
  EXPECT_TRUE(saw_motion);
  EXPECT_GE(Clock::now() - t0, 1500ms);
  EXPECT_EQ(input32(kIt116g, kItPosition), 3000);
  EXPECT_EQ(input32(kIt116g, kItPositionIn), 1181);  // 3000 / 2540 steps per inch, 0.001 in
  // The C142 on its own bus was polled all along.
  EXPECT_TRUE(client_->read_input(kC142, kInMotion, 1).ok());
}

}  // namespace
}  // namespace fieldgate::test
