// The real daemon against fieldgate-sim-whedco on a PTY, through Modbus TCP: two CMC-0 units
// (addresses 4 and 5, axes X and Y, model whedco-cmc-xy) on one line. Every test runs with the
// units in echo and in non-echo format, auto-detected and configured.
#include <gtest/gtest.h>

#include <thread>

#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// whedco-cmc-xy register map (see the model's header).
namespace in {  // input registers
constexpr int kUnitStatus = 0, kUnitFaultCode = 1, kUnitFaulted = 2;
constexpr int kXActual = 9, kXCommanded = 11, kXFaultCode = 15, kXFaulted = 16;
constexpr int kYActual = 18, kYFaultCode = 24, kYFaulted = 25;
constexpr int kDiagOnline = 1000, kDiagTransactions = 1004;
constexpr int kDiagLastDeviceError = 1010;
}  // namespace in
namespace hold {  // holding registers
constexpr int kXTarget = 0, kXAcceleration = 4, kXJogSpeed = 6, kXUnitRatio = 8;
constexpr int kYTarget = 9, kYUnitRatio = 17, kXyVelocity = 18, kV9 = 38;
constexpr int kCommand = 100, kActionStatus = 101, kActionError = 102;
constexpr int kAxes = 110, kAxis = 111;
}  // namespace hold
constexpr int kDiscreteFaulted = 1;  // unit_status bit faulted
constexpr int kClearFaults = 1, kMoveAbsolute = 3, kJogPositive = 5, kJogStop = 7;
constexpr int kDeviceFailure = 0x04, kTargetFailed = 0x0B;
constexpr int kStatusBusy = 1, kStatusDone = 2, kStatusError = 3;

struct Format {
  const char* name;
  std::vector<std::string> sim_flags;
  const char* address_suffix;
  int functional = 0;           // the non-echo FC number of Unit Functional (0, or 8 in the
                                // FCa-table reading); FC numbers are it plus the axis byte
  const char* baud = "115200";  // of the bus (and of the simulator's wire emulation)
};

void PrintTo(const Format& f, std::ostream* os) {
  *os << f.name;
}

class WhedcoEndToEnd : public PlantFixture<::testing::TestWithParam<Format>> {
 protected:
  void SetUp() override {
    const Format& f = GetParam();
    std::vector<std::string> argv{
        FIELDGATE_SIM_WHEDCO, "--link", "{link}", "--units", "4,5", "--axes", "XY", "--verbose"};
    argv.insert(argv.end(), f.sim_flags.begin(), f.sim_flags.end());
    const std::string suffix = f.address_suffix;
    const std::string nodes =
        "      - {name: cmc4, address: '4" + suffix +
        "', model: whedco-cmc-xy, unit_id: 1, poll: {slow: 300ms, variables: 500ms}}\n"
        "      - {name: cmc5, address: '5" +
        suffix + "', model: whedco-cmc-xy, unit_id: 2, poll: {slow: 300ms, variables: 500ms}}\n";
    SimulatedBus bus{"cmc-line", "whedco-cmc", argv, std::string("baud: ") + f.baud,
                     // The simulator paces a 9600-baud reply itself, and on a loaded host it
                     // can stall longer than 10 ms between two characters and answer 100-220 ms
                     // late (a device's UART does not; the gateway's own stalls are covered by
                     // what the OS buffers): a stall past the byte timeout is a garbled reply,
                     // one past the reply timeout a timeout, hence 200 and 40 ms, not 50 and 10.
                     "reply_timeout: 200ms, byte_timeout: 40ms, retries: 1, offline_after: 3, "
                     "probe_interval: 300ms",
                     nodes};
    start({bus});
    wait_online(
        {1, 2},
        [&](int unit) {
          return client_->read_input(unit, 0, 27).ok() && client_->read_holding(unit, 0, 52).ok();
        },
        30s);
  }

  uint32_t transactions(int unit) { return input_u32(unit, in::kDiagTransactions); }
};

TEST_P(WhedcoEndToEnd, BothUnitsReadAtRest) {
  for (int unit : {1, 2}) {
    EXPECT_EQ(client_->read_input_i32(unit, in::kXActual), 0);
    EXPECT_EQ(client_->read_input_i32(unit, in::kYActual), 0);
    EXPECT_EQ(input(unit, in::kXFaultCode), 8) << "Unit Functional";
    EXPECT_EQ(input(unit, in::kXFaulted), 0);
    EXPECT_EQ(input(unit, in::kUnitFaultCode), GetParam().functional);
    EXPECT_EQ(input(unit, in::kUnitFaulted), 0);
    EXPECT_EQ(input(unit, in::kUnitStatus), 0);
    EXPECT_EQ(input(unit, in::kDiagOnline), 1);
    EXPECT_EQ(holding(unit, hold::kXUnitRatio), 1);
    EXPECT_EQ(holding_i32(unit, hold::kXAcceleration), 80000) << "App. C default";
  }
}

TEST_P(WhedcoEndToEnd, MoveOnOneUnitWhileTheOtherKeepsUpdating) {
  // Unit 2 jogs X at 2000 pp/s, so its position changes on every poll.
  ASSERT_TRUE(client_->write_i32(2, hold::kXJogSpeed, 2000).ok());
  ASSERT_TRUE(client_->write_single(2, hold::kCommand, kJogPositive).ok());
  EXPECT_EQ(holding(2, hold::kActionStatus), kStatusDone);

  // Unit 1: 1000 pp per user unit, so every number crosses the wire divided by 1000.
  ASSERT_TRUE(client_->write_single(1, hold::kXUnitRatio, 1000).ok());
  ASSERT_TRUE(client_->write_i32(1, hold::kXyVelocity, 100000).ok());
  ASSERT_TRUE(client_->write_i32(1, hold::kXAcceleration, 1000000).ok());
  ASSERT_TRUE(client_->write_i32(1, hold::kXTarget, 250000).ok());
  ASSERT_TRUE(client_->write_single(1, hold::kAxes, 1).ok());
  ASSERT_TRUE(client_->write_single(1, hold::kCommand, kMoveAbsolute).ok());
  EXPECT_EQ(holding(1, hold::kActionStatus), kStatusBusy);

  int32_t last_other = *client_->read_input_i32(2, in::kXActual);
  const auto other_polled = transactions(2);
  bool saw_between = false;
  int other_advanced = 0;
  for (int i = 0; i < 10; ++i) {
    std::this_thread::sleep_for(200ms);
    const auto mine = client_->read_input_i32(1, in::kXActual);
    ASSERT_TRUE(mine);
    if (*mine > 0 && *mine < 250000) saw_between = true;
    const auto other = client_->read_input_i32(2, in::kXActual);
    ASSERT_TRUE(other);
    if (*other > last_other) ++other_advanced;
    last_other = *other;
  }
  EXPECT_GE(transactions(2), other_polled + 5) << "unit 2 polled during unit 1's move";
  EXPECT_TRUE(saw_between) << "the position moved through the registers";
  EXPECT_GE(other_advanced, 6);
  ASSERT_TRUE(wait_until([&] { return holding(1, hold::kActionStatus) == kStatusDone; }, 20s));
  EXPECT_EQ(client_->read_input_i32(1, in::kXActual), 250000);
  // Done waits for the fast class (positions) to be read again; RCa is polled less often.
  EXPECT_TRUE(
      wait_until([&] { return client_->read_input_i32(1, in::kXCommanded) == 250000; }, 10s));
  EXPECT_EQ(holding_i32(1, hold::kXTarget), 250000);
  EXPECT_EQ(holding_i32(1, hold::kXAcceleration), 1000000);
  EXPECT_EQ(client_->read_input_i32(1, in::kYActual), 0) << "Y was not in the axis set";
  // On the wire the numbers were user units: the family divided by the unit ratio.
  const std::string wire = plant_->sim().log();
  for (const char* sent : {"4URX1000\\r", "4VX100\\r", "4ACX1000\\r", "4AMX250\\r", "4RAX\\r"})
    EXPECT_NE(wire.find(sent), std::string::npos) << sent;

  ASSERT_TRUE(client_->write_single(2, hold::kCommand, kJogStop).ok());
  std::this_thread::sleep_for(300ms);
  const auto stopped = client_->read_input_i32(2, in::kXActual);
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(client_->read_input_i32(2, in::kXActual), stopped);
  EXPECT_GT(*stopped, 3000);
}

TEST_P(WhedcoEndToEnd, FaultSurfacesAndIsClearedFromThePlc) {
  plant_->sim().send_line("fault 5 Y 3");
  ASSERT_TRUE(wait_until([&] {
    return input(2, in::kYFaultCode) == 3 && input(2, in::kYFaulted) == 1 &&
           input(2, in::kUnitFaulted) == 1;
  })) << "Excessive Following Error reaches the PLC";
  EXPECT_EQ(input(2, in::kUnitFaultCode), GetParam().functional + 0x22)
      << "Y faulted and not functional";
  auto bits = client_->read_discrete(2, 0, 5);
  ASSERT_TRUE(bits.ok());
  EXPECT_EQ(bits.values[kDiscreteFaulted], 1);
  EXPECT_EQ(input(1, in::kUnitFaulted), 0) << "unit 1 is not affected";

  ASSERT_TRUE(client_->write_single(2, hold::kCommand, kClearFaults).ok());
  ASSERT_TRUE(wait_until([&] {
    return input(2, in::kYFaultCode) == 8 && input(2, in::kYFaulted) == 0 &&
           input(2, in::kUnitFaulted) == 0 && input(2, in::kUnitFaultCode) == GetParam().functional;
  }));

  // A fault during a move ends the action as failed.
  ASSERT_TRUE(client_->write_i32(2, hold::kYTarget, 1000000).ok());
  ASSERT_TRUE(client_->write_single(2, hold::kAxes, 2).ok());
  ASSERT_TRUE(client_->write_single(2, hold::kCommand, kMoveAbsolute).ok());
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(holding(2, hold::kActionStatus), kStatusBusy);
  plant_->sim().send_line("fault 5 Y A");
  ASSERT_TRUE(wait_until([&] { return holding(2, hold::kActionStatus) == kStatusError; }));
  EXPECT_EQ(holding(2, hold::kActionError), 0xfffe) << "ended by the failed condition";
  EXPECT_TRUE(wait_until([&] { return input(2, in::kYFaultCode) == 10; }));
  ASSERT_TRUE(client_->write_single(2, hold::kCommand, kClearFaults).ok());
}

TEST_P(WhedcoEndToEnd, RefusalsAndAnAbsentUnit) {
  // 100 pp/s is within the model's range but below the unit's 200 pp/s minimum: the unit
  // answers '?' and the write fails with 0x04.
  EXPECT_EQ(client_->write_i32(1, hold::kXJogSpeed, 100).exception, kDeviceFailure);
  EXPECT_EQ(input(1, in::kDiagLastDeviceError), 1);
  // Two axes where a jog takes one: the family does not send it.
  ASSERT_TRUE(client_->write_single(1, hold::kAxis, 3).ok());
  EXPECT_EQ(client_->write_single(1, hold::kCommand, kJogPositive).exception, kDeviceFailure);
  EXPECT_EQ(holding(1, hold::kActionError), 2);
  // Variables are internal units, both ways.
  ASSERT_TRUE(client_->write_i32(1, hold::kV9, -123456).ok());
  ASSERT_TRUE(wait_until([&] { return holding_i32(1, hold::kV9) == -123456; }));

  plant_->sim().send_line("unit-off 5");
  ASSERT_TRUE(wait_until(
      [&] { return client_->read_input(2, in::kXActual, 2).exception == kTargetFailed; }));
  // Unit 1 keeps being polled, and answering, while its neighbour is absent: counted in
  // transactions rather than timed, so a loaded machine slows it without failing it.
  const auto polled = transactions(1);
  EXPECT_TRUE(wait_until([&] { return transactions(1) >= polled + 10; }, 20s))
      << "unit 1 not polled beside an absent unit: " << transactions(1) - polled;
  EXPECT_EQ(input(1, in::kDiagOnline), 1);
  EXPECT_EQ(client_->read_input(2, in::kXActual, 2).exception, kTargetFailed) << "unit 5 is back";
  plant_->sim().send_line("unit-on 5");
  ASSERT_TRUE(wait_until([&] { return client_->read_input(2, in::kXActual, 2).ok(); }));
  // A slowly polled point read before the unit went away is stale (0x0B) until its class is
  // polled again (issue 49: nothing stale served as fresh); then it reads its value.
  EXPECT_TRUE(wait_until([&] { return holding(2, hold::kYUnitRatio) == 1; }))
      << holding(2, hold::kYUnitRatio);
}

// Issue 12: a unit slower than the reply timeout. No value served as good may be another
// request's, no write may be confirmed by another request's reply.
TEST_P(WhedcoEndToEnd, SlowerThanTheReplyTimeoutNothingWrongIsServed) {
  ASSERT_TRUE(client_->write_i32(1, hold::kV9, 1234).ok());
  ASSERT_TRUE(wait_until([&] { return holding_i32(1, hold::kV9) == 1234; }));
  plant_->sim().send_line("delay 250");  // reply_timeout is 200 ms
  int wrong = 0;
  int confirmed = 0;
  const auto until = std::chrono::steady_clock::now() + 3s;
  int32_t written = 1234;
  while (std::chrono::steady_clock::now() < until) {
    if (const auto x = client_->read_input_i32(1, in::kXActual); x && *x != 0) ++wrong;
    if (const auto v = holding_i32(1, hold::kV9); v && *v != written && *v != 1234) ++wrong;
    if (client_->write_i32(1, hold::kV9, 77).ok()) {
      ++confirmed;
      written = 77;
    }
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_EQ(wrong, 0);
  plant_->sim().send_line("delay 0");
  // A write confirmed during the delay ran on the unit: its value is what the unit reports.
  if (confirmed > 0) {
    EXPECT_TRUE(wait_until([&] { return holding_i32(1, hold::kV9) == 77; }, 30s));
  }
  // The node went offline meanwhile; it is probed back (no time limit is asserted here).
  ASSERT_TRUE(wait_until([&] { return client_->write_i32(1, hold::kV9, 5).ok(); }, 30s));
  ASSERT_TRUE(wait_until([&] { return holding_i32(1, hold::kV9) == 5; }, 30s));
}

INSTANTIATE_TEST_SUITE_P(
    Formats, WhedcoEndToEnd,
    ::testing::Values(
        Format{"EchoAutoDetected", {}, ""},
        Format{"NonEchoAutoDetected", {"--non-echo", "all"}, ""},
        Format{"EchoConfiguredTerminalReplies", {"--reply-style", "terminal"}, "/echo"},
        Format{"NonEchoConfigured", {"--non-echo", "all"}, "/non-echo"},
        // The readings of what the manual excerpt leaves open (README).
        Format{"NonEchoFcTableCodes", {"--non-echo", "all", "--fc-table-codes"}, "", 8},
        Format{"HexStatusWords", {"--status-format", "hex"}, ""},
        Format{"BinaryStatusWordsNonEcho", {"--status-format", "binary", "--non-echo", "all"}, ""},
        Format{"InlineReplies", {"--reply-style", "inline"}, ""},
        Format{"NonEchoWireTime9600",
               {"--non-echo", "all", "--emulate-wire", "--baud", "9600"},
               "/non-echo",
               0,
               "9600"}),
    [](const ::testing::TestParamInfo<Format>& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate::test
