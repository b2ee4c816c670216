// Issue 26, property test: random interleavings of late, dropped, garbled and truncated replies
// around reads and writes, against the Techno simulator (one C142, which executes every line it
// hears and journals it). Whatever the faults:
//  - every write answered success appears executed in the device journal, answered by its own
//    handshake `0`, and that reply reached the gateway unharmed (every command of the family is
//    answered by the same one character, so only the order of the line ties it to its request);
//  - every value served as good equals the controller's value (the axes stand at distinct
//    positions and the input port reads a constant, so a position reply, a peek reply and a
//    handshake taken for one another show).
// At 19200 baud, and at 9600 with wire-time emulation.
#include <gtest/gtest.h>

#include <string>

#include "fault_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// config/models/techno-c142.yaml, in declaration order.
constexpr int kPositionX = 0, kPositionY = 2, kPositionZ = 4, kInMotion = 6, kInputs = 13,
              kMotionFault = 14, kMotionError = 15;  // input registers
constexpr int kOutputs1 = 1;                         // holding: B65529,{value}
constexpr int kCommand = 100, kStatus = 101;
constexpr int kTargetX = 110, kTargetY = 112, kTargetZ = 114;
constexpr int kMoveAbsolute = 3;
constexpr int kUnit = 1;

constexpr int32_t kX = 1201, kY = 602, kZ = 303;
constexpr uint16_t kInputMask = 0x5A;

class TechnoFaultProperty : public PlantFixture<::testing::TestWithParam<FaultRun>> {
 protected:
  void SetUp() override {
    SimulatedBus bus = fault_bus("techno", "techno-c",
                                 {FIELDGATE_SIM_TECHNO, "--link", "{link}", "--variant", "c142",
                                  "--axes", "7", "--journal", "{dir}/journal"},
                                 GetParam());
    if (!GetParam().slow_wire) bus.serial = "baud: 19200";
    bus.nodes = "      - {name: c142, address: 0, model: techno-c142, unit_id: 1}\n";
    start({bus});
    wait_inputs({kUnit}, kPositionX, 2, 20s);
    plant_->sim().send_line("inputs " + std::to_string(kInputMask));
    ASSERT_TRUE(client_->write_i32(kUnit, kTargetX, kX).ok());
    ASSERT_TRUE(client_->write_i32(kUnit, kTargetY, kY).ok());
    ASSERT_TRUE(client_->write_i32(kUnit, kTargetZ, kZ).ok());
    // A loaded host can make the move's handshake late before any fault is injected (the family
    // then stops the axes and the outcome is unknown): move again until one ends done.
    bool moved = false;
    const auto give_up = std::chrono::steady_clock::now() + 60s;
    while (!moved && std::chrono::steady_clock::now() < give_up) {
      wait_until([&] { return client_->read_input(kUnit, kPositionX, 2).ok(); }, 5s);
      if (!client_->write_single(kUnit, kCommand, kMoveAbsolute).ok()) continue;
      wait_until([&] { return holding(kUnit, kStatus) != 1; }, 20s);
      moved = holding(kUnit, kStatus) == 2;
    }
    ASSERT_TRUE(moved) << plant_->daemon().log();
    ASSERT_TRUE(wait_until(
        [&] {
          return client_->read_input_i32(kUnit, kPositionX) == kX &&
                 client_->read_input_i32(kUnit, kPositionY) == kY &&
                 client_->read_input_i32(kUnit, kPositionZ) == kZ &&
                 input(kUnit, kInputs) == kInputMask;
        },
        20s))
        << plant_->daemon().log();
  }
};

TEST_P(TechnoFaultProperty, NoWriteConfirmedByAnotherReplyAndNoWrongValueServed) {
  // Taken offline by the faults, the node is only probed now and then: the writes wait for
  // it, so that they reach the controller rather than being refused at the gateway.
  FaultProperty property{
      .units = 1, .inputs = {kPositionX, kMotionError + 1}, .online = {kPositionX, 2}};
  property.check_read = [](ModbusClient&, int, const ModbusResult& r, FaultReads& reads) {
    if (!r.ok()) return;
    if (i32_at(r, kPositionX) != kX) reads.wrong_value("x", i32_at(r, kPositionX));
    if (i32_at(r, kPositionY) != kY) reads.wrong_value("y", i32_at(r, kPositionY));
    if (i32_at(r, kPositionZ) != kZ) reads.wrong_value("z", i32_at(r, kPositionZ));
    if (r.values[kInMotion] != 0) reads.wrong_value("in_motion", r.values[kInMotion]);
    if (r.values[kInputs] != kInputMask) reads.wrong_value("inputs", r.values[kInputs]);
    if (r.values[kMotionFault] != 0) reads.wrong_value("motion_fault", r.values[kMotionFault]);
    if (r.values[kMotionError] != 0) reads.wrong_value("motion_error", r.values[kMotionError]);
  };
  // Each write is unique (a distinct output byte), so the journal tells whose reply
  // confirmed what.
  property.write = [](ModbusClient& client, int i, int, std::mt19937&) {
    return FaultWrite{
        .value = i,
        .exception = client.write_single(kUnit, kOutputs1, static_cast<uint16_t>(i)).exception};
  };
  property.check_confirmed = [](const FaultWrite& w, const std::vector<JournalEntry>& journal) {
    // Its own execution, answered `0`, and that `0` reached the gateway unharmed. The
    // controller answers through emit(), which journals the reply on a line of its own
    // (empty request); a command that does not wait for a motion answers while it runs,
    // so its reply's line comes right before its own.
    const std::string request = "@0B65529," + std::to_string(w.value) + "\\r";
    const auto it = find_request(journal, request);
    ASSERT_NE(it, journal.end()) << "output byte " << w.value
                                 << " was confirmed but the controller never ran it";
    ASSERT_NE(it, journal.begin()) << "output byte " << w.value;
    const auto reply = std::prev(it);
    EXPECT_EQ(reply->request, "") << "output byte " << w.value;
    EXPECT_EQ(reply->reply, "0") << "output byte " << w.value;
    EXPECT_EQ(reply->fault, "") << "output byte " << w.value
                                << " was confirmed, but the controller's own reply to it was "
                                << reply->fault << ": another reply confirmed it";
  };
  run_fault_property(*plant_, client_, GetParam().seed, property);
}

INSTANTIATE_TEST_SUITE_P(Interleavings, TechnoFaultProperty, ::testing::ValuesIn(kFastThenSlowRuns),
                         fault_run_name);

}  // namespace
}  // namespace fieldgate::test
