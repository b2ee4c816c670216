// Issue 26, property test: random interleavings of late, dropped, garbled and truncated result
// lines around reads and writes, against the IMS party-line simulator (which executes every line
// it hears and journals it). Whatever the faults:
//  - every value served as good equals the unit's value (each axis has a distinct, constant
//    position and inputs, and stands still, so a result taken from another exchange shows);
//  - every write answered success appears executed in the device journal.
// A write on the party line is confirmed by its echo (drivers/ims_party_line/README.md), which the
// units send as the characters arrive; chaos disturbs what follows it (results, the completion's
// CR LF). So a confirmed write needs its own journal line, whatever became of its completion.
// At 9600 baud with wire-time emulation (the manual's rate), and at 115200.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <memory>
#include <random>
#include <thread>

#include "fault_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// config/models/ims-indexer.yaml
constexpr int kPosition = 0;         // input registers 0-1, int32 (Z)
constexpr int kStatus = 2;           // ^
constexpr int kIo = 5;               // A129: inputs IN1-IN3 in bits 0-2, outputs in bits 3-5
constexpr int kInitialVelocity = 3;  // holding, write-only: I{value}

struct FaultRun {
  const char* name;
  bool slow_wire;  // 9600 baud with wire-time emulation
  unsigned seed;
};

const std::map<int, char> kName = {{1, 'A'}, {2, 'B'}, {3, 'C'}};               // by unit ID
const std::map<int, int32_t> kPositionOf = {{1, 1001}, {2, -2002}, {3, 3003}};  // by unit ID
const std::map<int, uint16_t> kInputsOf = {{1, 1}, {2, 2}, {3, 4}};             // by unit ID

const char* kNodes =
    "      - {name: axis_a, address: A, model: ims-indexer, unit_id: 1}\n"
    "      - {name: axis_b, address: B, model: ims-indexer, unit_id: 2}\n"
    "      - {name: axis_c, address: C, model: ims-indexer, unit_id: 3}\n";

class ImsFaultProperty : public PlantFixture<::testing::TestWithParam<FaultRun>> {
 protected:
  void SetUp() override {
    const FaultRun run = GetParam();
    SimulatedBus bus;
    bus.name = "ims";
    bus.protocol = "ims-party-line";
    bus.sim_argv = {FIELDGATE_SIM_IMS, "--link",    "{link}",       "--axes",
                    "A,B,C",           "--journal", "{dir}/journal"};
    if (run.slow_wire) {
      for (const char* a : {"--baud", "9600", "--emulate-wire"}) bus.sim_argv.push_back(a);
      bus.serial = "baud: 9600";
    }
    bus.timing =
        // A line this bad would take nodes offline every few polls with offline_after: 3 (it
        // counts attempts); the property is about the exchanges, so keep them online.
        "reply_timeout: 100ms, byte_timeout: 30ms, retries: 1, offline_after: 10, "
        "probe_interval: 300ms";
    bus.nodes = kNodes;
    start({bus});
    for (const auto& [unit, name] : kName) {
      plant_->sim().send_line("position " + std::string(1, name) + " " +
                              std::to_string(kPositionOf.at(unit)));
      plant_->sim().send_line("inputs " + std::string(1, name) + " " +
                              std::to_string(kInputsOf.at(unit)));
    }
    for (const auto& [unit, name] : kName)
      ASSERT_TRUE(wait_until(
          [&, unit = unit] {
            return client_->read_input_i32(unit, kPosition) == kPositionOf.at(unit) &&
                   input(unit, kIo) == kInputsOf.at(unit);
          },
          20s))
          << "unit " << unit << "\n"
          << plant_->daemon().log();
  }
};

TEST_P(ImsFaultProperty, NoWriteConfirmedThatDidNotRunAndNoWrongValueServed) {
  const FaultRun run = GetParam();
  // Late results start 150 ms after the request, well past the 100 ms reply timeout and inside
  // the late-reply window (5 reply timeouts).
  plant_->sim().send_line("chaos " + std::to_string(run.seed) + " 25 5 5 5 150");

  std::atomic<bool> running{true};
  std::atomic<int> good_reads{0}, wrong_reads{0};
  std::string first_wrong;
  std::thread reader([&] {
    auto second = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
    std::mt19937 random(run.seed + 1000);
    while (running) {
      const int unit = 1 + static_cast<int>(random() % 3);
      auto r = second->read_input(unit, kPosition, 6);
      // A connection that missed an answer would take it for the next one's: start afresh.
      if (!answered(r.exception))
        second = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
      if (!r.ok()) continue;
      ++good_reads;
      const int32_t position = static_cast<int32_t>((uint32_t{r.values[0]} << 16) | r.values[1]);
      if (position != kPositionOf.at(unit) && wrong_reads++ == 0)
        first_wrong = "unit " + std::to_string(unit) + " position " + std::to_string(position);
      if (r.values[kStatus] != 0 && wrong_reads++ == 0)
        first_wrong = "unit " + std::to_string(unit) + " status " + std::to_string(r.values[2]);
      if (r.values[kIo] != kInputsOf.at(unit) && wrong_reads++ == 0)
        first_wrong = "unit " + std::to_string(unit) + " io " + std::to_string(r.values[kIo]);
    }
  });

  // Each write is unique (an initial velocity ending in the unit ID), so the journal tells what
  // ran. I changes nothing the polls read.
  struct Write {
    int unit;
    int value;
    int exception;
  };
  std::vector<Write> writes;
  std::mt19937 random(run.seed);
  // At least 24 writes, and more until a few went through (how many do depends on the load of
  // the test machine as much as on the faults: a failed proof answers 0x0B without sending).
  int confirmed = 0;
  for (int i = 1; i <= 24 || (confirmed < 4 && i <= 96); ++i) {
    const int unit = 1 + static_cast<int>(random() % 3);
    // A unit taken offline by the faults is only probed now and then: wait for it, so that
    // writes reach devices rather than being refused at the gateway.
    wait_until([&] { return client_->read_input(unit, kPosition, 2).ok(); }, 3s);
    const int value = 1000 + i * 10 + unit;
    writes.push_back({unit, value, client_->write_single(unit, kInitialVelocity, value).exception});
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
    const std::string request =
        std::string(1, kName.at(w.unit)) + "I" + std::to_string(w.value) + "\\n";
    const auto it = std::find_if(journal.begin(), journal.end(),
                                 [&](const JournalEntry& e) { return e.request == request; });
    EXPECT_NE(it, journal.end()) << "I" << w.value << " for unit " << w.unit
                                 << " was confirmed but the unit never ran it";
  }
  expect_faults_and_confirmed_writes(successes, unknown, writes.size(), journal);
}

INSTANTIATE_TEST_SUITE_P(Interleavings, ImsFaultProperty,
                         ::testing::Values(FaultRun{"wire9600_seed1", true, 1},
                                           FaultRun{"wire9600_seed2", true, 2},
                                           FaultRun{"fast_seed3", false, 3},
                                           FaultRun{"fast_seed4", false, 4}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate::test
