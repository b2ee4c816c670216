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

#include <algorithm>
#include <atomic>
#include <memory>
#include <random>
#include <thread>

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

struct FaultRun {
  const char* name;
  bool slow_wire;  // 9600 baud with wire-time emulation
  unsigned seed;
};

class TechnoFaultProperty : public PlantFixture<::testing::TestWithParam<FaultRun>> {
 protected:
  void SetUp() override {
    const FaultRun run = GetParam();
    SimulatedBus bus;
    bus.name = "techno";
    bus.protocol = "techno-c";
    bus.sim_argv = {
        FIELDGATE_SIM_TECHNO, "--link",       "{link}", "--variant", "c142", "--axes", "7",
        "--journal",          "{dir}/journal"};
    if (run.slow_wire) {
      for (const char* a : {"--baud", "9600", "--emulate-wire"}) bus.sim_argv.push_back(a);
      bus.serial = "baud: 9600";
    } else {
      bus.serial = "baud: 19200";
    }
    bus.timing =
        // A line this bad would take the node offline every few polls with offline_after: 3 (it
        // counts attempts); the property is about the exchanges, so keep it online.
        "reply_timeout: 100ms, byte_timeout: 10ms, retries: 1, offline_after: 10, "
        "probe_interval: 300ms";
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
  const FaultRun run = GetParam();
  // Late replies start 150 ms after the request, well past the 100 ms reply timeout.
  plant_->sim().send_line("chaos " + std::to_string(run.seed) + " 25 5 5 5 150");

  std::atomic<bool> running{true};
  std::atomic<int> good_reads{0}, wrong_reads{0};
  std::string first_wrong;
  std::thread reader([&] {
    auto second = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
    const auto wrong = [&](const std::string& what, long value) {
      if (wrong_reads++ == 0) first_wrong = what + " " + std::to_string(value);
    };
    while (running) {
      auto r = second->read_input(kUnit, kPositionX, kMotionError + 1);
      // A connection that missed an answer would take it for the next one's: start afresh.
      if (!answered(r.exception))
        second = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
      if (!r.ok()) continue;
      ++good_reads;
      const auto i32 = [&](int address) {
        return static_cast<int32_t>((uint32_t{r.values[address]} << 16) | r.values[address + 1]);
      };
      if (i32(kPositionX) != kX) wrong("x", i32(kPositionX));
      if (i32(kPositionY) != kY) wrong("y", i32(kPositionY));
      if (i32(kPositionZ) != kZ) wrong("z", i32(kPositionZ));
      if (r.values[kInMotion] != 0) wrong("in_motion", r.values[kInMotion]);
      if (r.values[kInputs] != kInputMask) wrong("inputs", r.values[kInputs]);
      if (r.values[kMotionFault] != 0) wrong("motion_fault", r.values[kMotionFault]);
      if (r.values[kMotionError] != 0) wrong("motion_error", r.values[kMotionError]);
    }
  });

  // Each write is unique (a distinct output byte), so the journal tells whose reply confirmed
  // what.
  struct Write {
    int value;
    int exception;
  };
  std::vector<Write> writes;
  std::mt19937 random(run.seed);
  // At least 24 writes, and more until a few went through (how many do depends on the load of
  // the test machine as much as on the faults).
  int confirmed = 0;
  for (int i = 1; i <= 24 || (confirmed < 4 && i <= 96); ++i) {
    // Taken offline by the faults, the node is only probed now and then: wait for it, so that
    // writes reach the controller rather than being refused at the gateway.
    wait_until([&] { return client_->read_input(kUnit, kPositionX, 2).ok(); }, 3s);
    writes.push_back(
        {i, client_->write_single(kUnit, kOutputs1, static_cast<uint16_t>(i)).exception});
    // No answer is no confirmation; a fresh connection, so that the late answer is not
    // taken for the next write's.
    if (!answered(writes.back().exception)) {
      writes.back().exception = kNoAnswer;
      client_ = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
    }
    if (writes.back().exception == 0) ++confirmed;
    std::this_thread::sleep_for(std::chrono::milliseconds(random() % 40));
  }
  plant_->sim().send_line("chaos off");
  running = false;
  reader.join();

  EXPECT_EQ(wrong_reads.load(), 0) << first_wrong;
  EXPECT_GT(good_reads.load(), 10);

  const auto journal = read_journal(plant_->dir() / "journal");
  int successes = 0, unknown = 0;
  for (const auto& w : writes) {
    EXPECT_TRUE(expected_write_outcome(w.exception)) << "exception " << w.exception;
    if (w.exception == kTargetFailed) ++unknown;
    if (w.exception != 0) continue;
    ++successes;
    // Its own execution, answered `0`, and that `0` reached the gateway unharmed. The
    // controller answers through emit(), which journals the reply on a line of its own (empty
    // request); a command that does not wait for a motion answers while it runs, so its reply's
    // line comes right before its own.
    const std::string request = "@0B65529," + std::to_string(w.value) + "\\r";
    const auto it = std::find_if(journal.begin(), journal.end(),
                                 [&](const JournalEntry& e) { return e.request == request; });
    ASSERT_NE(it, journal.end()) << "output byte " << w.value
                                 << " was confirmed but the controller never ran it";
    ASSERT_NE(it, journal.begin()) << "output byte " << w.value;
    const auto reply = std::prev(it);
    EXPECT_EQ(reply->request, "") << "output byte " << w.value;
    EXPECT_EQ(reply->reply, "0") << "output byte " << w.value;
    EXPECT_EQ(reply->fault, "") << "output byte " << w.value
                                << " was confirmed, but the controller's own reply to it was "
                                << reply->fault << ": another reply confirmed it";
  }
  expect_faults_and_confirmed_writes(successes, unknown, writes.size(), journal);
}

INSTANTIATE_TEST_SUITE_P(Interleavings, TechnoFaultProperty,
                         ::testing::Values(FaultRun{"fast_seed1", false, 1},
                                           FaultRun{"fast_seed2", false, 2},
                                           FaultRun{"wire9600_seed3", true, 3},
                                           FaultRun{"wire9600_seed4", true, 4}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate::test
