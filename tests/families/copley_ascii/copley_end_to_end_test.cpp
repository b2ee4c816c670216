// The real daemon against the Copley simulator on a PTY, through Modbus TCP (libmodbus).
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <thread>

#include "copley_amplifiers.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// Fixed places of the register map (mapping/register_map.hpp, README).
constexpr int kPosition = 0;        // input registers 0-1: motor_position
constexpr int kDesiredState = 0;    // holding 0: desired_state
constexpr int kCommand = 100;       // holding 100: action command
constexpr int kActionStatus = 101;  // 0 idle, 1 busy, 2 done, 3 error
constexpr int kActionError = 102;
constexpr int kSetpointTarget = 110;  // holding 110-111: target
constexpr int kSetpointEnableMode = 122;
constexpr int kDiagOnline = 1000;
constexpr int kDiagConsecutiveTimeouts = 1003;
constexpr int kDiagLastDeviceError = 1010;
constexpr int kDiagNodeState = 1014;
constexpr int kEnable = 1, kMoveAbsolute = 3;

constexpr int kIllegalFunction = 0x01, kIllegalAddress = 0x02, kIllegalValue = 0x03,
              kDeviceFailure = 0x04, kPathUnavailable = 0x0A, kTargetFailed = 0x0B;

// Configured, but not on the simulated line.
const char* kAbsentAmplifier =
    "      - {name: amp7, address: 7, model: copley-amplifier, unit_id: 4}\n";

class CopleyEndToEnd : public PlantTest {
 protected:
  void SetUp() override {
    start(amplifier_plant(kAbsentAmplifier));
    // Position, velocity, event and trajectory status: the fast poll class, all polled once.
    wait_inputs({1, 2, 3}, kPosition, 7);
  }

  int action_status(int unit) { return holding(unit, kActionStatus); }
};

TEST_F(CopleyEndToEnd, ReadsPositionAndStatusOfEveryNode) {
  for (int unit : {1, 2, 3}) {
    EXPECT_EQ(client_->read_input_i32(unit, kPosition), 0);
    auto diag = client_->read_input(unit, kDiagOnline, 1);
    ASSERT_TRUE(diag.ok());
    EXPECT_EQ(diag.values[0], 1);
    // disabled_by_software (0xa0 bit 12) is the 10th named bit: discrete input 9.
    auto bits = client_->read_discrete(unit, 0, 18);
    ASSERT_TRUE(bits.ok());
    EXPECT_EQ(bits.values[9], 1) << "amplifier starts disabled";
  }
}

TEST_F(CopleyEndToEnd, ConfirmedMoveReachesTarget) {
  ASSERT_TRUE(client_->write_i32(2, kSetpointTarget, 5000).ok());
  auto target = client_->read_holding(2, kSetpointTarget, 2);
  ASSERT_TRUE(target.ok());
  EXPECT_EQ(target.values, (std::vector<uint16_t>{0, 5000}));

  ASSERT_TRUE(client_->write_single(2, kCommand, kEnable).ok());
  EXPECT_EQ(action_status(2), 2);  // enable has no completion condition: done once confirmed
  ASSERT_TRUE(client_->write_single(2, kCommand, kMoveAbsolute).ok());
  // The write was confirmed by the amplifier; the move itself is now under way.
  EXPECT_EQ(action_status(2), 1);
  ASSERT_TRUE(wait_until([&] { return action_status(2) == 2; }, 20s));
  EXPECT_EQ(client_->read_input_i32(2, kPosition), 5000);
  // The other axes did not move.
  EXPECT_EQ(client_->read_input_i32(3, kPosition), 0);
}

TEST_F(CopleyEndToEnd, DeviceErrorGivesException04AndTheCode) {
  // A move while disabled: the amplifier answers e 14 (unknown axis state) to t 1.
  auto r = client_->write_single(1, kCommand, kMoveAbsolute);
  EXPECT_EQ(r.exception, kDeviceFailure);
  EXPECT_EQ(action_status(1), 3);
  auto code = client_->read_holding(1, kActionError, 1);
  ASSERT_TRUE(code.ok());
  EXPECT_EQ(code.values[0], 14);
  auto diag = client_->read_input(1, kDiagLastDeviceError, 1);
  ASSERT_TRUE(diag.ok());
  EXPECT_EQ(diag.values[0], 14);
  // A point write the amplifier refuses: desired state 7 is no valid mode.
  EXPECT_EQ(client_->write_single(1, kDesiredState, 7).exception, kDeviceFailure);
  // The node is still online and serving.
  EXPECT_TRUE(client_->read_input(1, kPosition, 2).ok());
}

TEST_F(CopleyEndToEnd, MissingNodeGoesOfflineWithException0BWhileOthersUpdate) {
  ASSERT_TRUE(wait_until([&] {
    auto d = client_->read_input(4, kDiagNodeState, 1);
    return d.ok() && d.values[0] == 2;
  }));
  EXPECT_EQ(client_->read_input(4, kPosition, 2).exception, kTargetFailed);
  EXPECT_EQ(client_->write_single(4, kCommand, kEnable).exception, kTargetFailed);
  EXPECT_EQ(client_->read_input(4, kDiagOnline, 1).values, std::vector<uint16_t>{0});
  // Neighbours keep being polled: their last good poll stays fresh.
  for (int i = 0; i < 5; ++i) {
    std::this_thread::sleep_for(200ms);
    for (int unit : {1, 2, 3}) {
      auto age = client_->read_input(unit, kDiagOnline + 1, 2);
      ASSERT_TRUE(age.ok());
      const uint32_t ms = (static_cast<uint32_t>(age.values[0]) << 16) | age.values[1];
      EXPECT_LT(ms, 1000u) << "unit " << unit;
    }
  }
}

TEST_F(CopleyEndToEnd, ProtocolExceptions) {
  EXPECT_EQ(client_->read_input(1, 500, 1).exception, kIllegalAddress);  // unmapped
  EXPECT_EQ(client_->read_input(1, 998, 4).exception, kIllegalAddress);  // runs into a gap
  EXPECT_EQ(client_->write_single(1, kSetpointTarget, 1).exception, kIllegalValue);  // half int32
  EXPECT_EQ(client_->write_single(1, kSetpointEnableMode, 5).exception, kIllegalValue);  // < min
  EXPECT_EQ(client_->write_single(1, kCommand, 99).exception, kIllegalValue);  // no such action
  EXPECT_EQ(client_->write_single(1, kActionStatus, 0).exception, kIllegalAddress);  // read-only
  EXPECT_EQ(client_->write_coil(1, 0, true).exception, kIllegalAddress);             // no coils
  EXPECT_EQ(client_->read_input(9, 0, 1).exception, kPathUnavailable);               // no such unit
  EXPECT_EQ(client_->write_single(1, kSetpointEnableMode, 31).exception, 0);
  (void)kIllegalFunction;
}

TEST_F(CopleyEndToEnd, NodeOfflineAndBackOnline) {
  plant_->sim().send_line("node-off 3");
  ASSERT_TRUE(
      wait_until([&] { return client_->read_input(2, kPosition, 2).exception == kTargetFailed; }));
  auto diag = client_->read_input(2, kDiagOnline, 4);
  ASSERT_TRUE(diag.ok());
  EXPECT_EQ(diag.values[0], 0);
  EXPECT_GE(diag.values[3], 3);  // consecutive timeouts reached offline_after
  // Unit 3 is unaffected.
  EXPECT_TRUE(client_->read_input(3, kPosition, 2).ok());
  plant_->sim().send_line("node-on 3");
  ASSERT_TRUE(wait_until([&] { return client_->read_input(2, kPosition, 2).ok(); }));
  auto again = client_->read_input(2, kDiagConsecutiveTimeouts, 1);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again.values[0], 0);
  const std::string log = plant_->daemon().log();
  EXPECT_NE(log.find("node amp3 (3) offline"), std::string::npos) << log;
  EXPECT_NE(log.find("node amp3 (3) online again"), std::string::npos) << log;
}

TEST_F(CopleyEndToEnd, TwoClientsAtOnce) {
  ModbusClient second("127.0.0.1", plant_->port());
  std::atomic<bool> moving{true};
  std::atomic<int> reads_ok{0}, reads_failed{0};
  std::thread reader([&] {
    while (moving) {
      if (second.read_input(3, kPosition, 2).ok())
        ++reads_ok;
      else
        ++reads_failed;
      // Reads overlap the writes either way; unpaced, the reader and the daemon serving it would
      // take both cores of a small test machine from everything else running.
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  // The reader is joined before any assertion can leave the test (a joinable thread aborts).
  const bool enabled = client_->write_single(2, kCommand, kEnable).ok();
  const bool targeted = enabled && client_->write_i32(2, kSetpointTarget, -3000).ok();
  const bool started = targeted && client_->write_single(2, kCommand, kMoveAbsolute).ok();
  const bool done = started && wait_until([&] { return action_status(2) == 2; }, 20s);
  moving = false;
  reader.join();
  ASSERT_TRUE(enabled);
  ASSERT_TRUE(targeted);
  ASSERT_TRUE(started);
  ASSERT_TRUE(done);
  EXPECT_EQ(client_->read_input_i32(2, kPosition), -3000);
  EXPECT_GT(reads_ok.load(), 10);
  EXPECT_EQ(reads_failed.load(), 0);
}

TEST_F(CopleyEndToEnd, HalfSentRequestDoesNotStallOthers) {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(plant_->port()));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  // MBAP header of a read request, cut off before the PDU.
  const unsigned char half[] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x01};
  ASSERT_EQ(::send(s, half, sizeof half, 0), static_cast<ssize_t>(sizeof half));
  for (int i = 0; i < 20; ++i) EXPECT_TRUE(client_->read_input(1, kPosition, 2).ok());
  ModbusClient third("127.0.0.1", plant_->port());
  EXPECT_TRUE(third.read_input(2, kPosition, 2).ok());
  ::close(s);
}

}  // namespace
}  // namespace fieldgate::test
