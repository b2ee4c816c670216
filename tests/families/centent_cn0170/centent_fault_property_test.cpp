// Issue 26, property test: random interleavings of late, dropped, garbled and truncated replies
// around reads and writes, against the Centent CN0170 simulator (a chain of three units that
// executes every line it traps and journals it). Whatever the faults:
//  - every value served as good equals the unit's value (each unit's analog input 1 is distinct
//    and constant, the axes stand still, and every acceleration written to a unit ends in its
//    number, so a reply taken from another exchange shows);
//  - every write answered success appears executed in the device journal, and the M? that
//    confirmed it (the CN0170 acknowledges nothing: drivers/centent_cn0170/README.md) was
//    answered there, on the same transmission, by a reply that reached the gateway unharmed.
// At 115200 baud, and at 9600 with wire-time emulation.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
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

// config/models/centent-cn0170.yaml
constexpr int kXPosition = 0, kYPosition = 2, kMotion = 4, kAnalog1 = 12;  // input registers
constexpr int kYAcceleration = 1;  // holding: YA?, YA=0{value:X}H
constexpr int kFactoryAcceleration = 156;

struct FaultRun {
  const char* name;
  bool slow_wire;  // 9600 baud with wire-time emulation
  unsigned seed;
};

// By unit ID; the chain's unit numbers are one less.
const std::map<int, uint16_t> kAnalogOf = {{1, 0x11}, {2, 0x22}, {3, 0x44}};

std::string nodes() {
  std::string out;
  for (int unit = 0; unit < 3; ++unit)
    out += "      - {name: cn" + std::to_string(unit) + ", address: " + std::to_string(unit) +
           ", model: centent-cn0170, unit_id: " + std::to_string(unit + 1) +
           ", poll: {fast: 200ms, slow: 500ms}}\n";
  return out;
}

class CententFaultProperty : public PlantFixture<::testing::TestWithParam<FaultRun>> {
 protected:
  void SetUp() override {
    const FaultRun run = GetParam();
    SimulatedBus bus;
    bus.name = "chain";
    bus.protocol = "centent-cn0170";
    bus.sim_argv = {FIELDGATE_SIM_CENTENT, "--link",       "{link}", "--units", "0,1,2",
                    "--journal",           "{dir}/journal"};
    if (run.slow_wire) {
      for (const char* a : {"--baud", "9600", "--emulate-wire"}) bus.sim_argv.push_back(a);
      bus.serial = "baud: 9600";
    }
    bus.timing =
        // A line this bad would take nodes offline every few polls with offline_after: 3 (it
        // counts attempts); the property is about the exchanges, so keep them online.
        "reply_timeout: 100ms, byte_timeout: 10ms, retries: 1, offline_after: 10, "
        "probe_interval: 300ms";
    bus.nodes = nodes();
    start({bus});
    for (const auto& [unit, value] : kAnalogOf)
      plant_->sim().send_line("analog " + std::to_string(unit - 1) + " 1 " + std::to_string(value));
    for (const auto& [unit, value] : kAnalogOf)
      ASSERT_TRUE(wait_until(
          [&, unit = unit, value = value] { return input(unit, kAnalog1) == value; }, 20s))
          << "unit " << unit << "\n"
          << plant_->daemon().log();
  }
};

TEST_P(CententFaultProperty, NoWriteConfirmedByAnotherReplyAndNoWrongValueServed) {
  const FaultRun run = GetParam();
  // Late replies start 150 ms after the request, well past the 100 ms reply timeout.
  plant_->sim().send_line("chaos " + std::to_string(run.seed) + " 25 5 5 5 150");

  std::atomic<bool> running{true};
  std::atomic<int> good_reads{0}, wrong_reads{0};
  std::string first_wrong;
  std::thread reader([&] {
    auto second = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
    std::mt19937 random(run.seed + 1000);
    const auto wrong = [&](int unit, const std::string& what, long value) {
      if (wrong_reads++ == 0)
        first_wrong = "unit " + std::to_string(unit) + " " + what + " " + std::to_string(value);
    };
    while (running) {
      const int unit = 1 + static_cast<int>(random() % 3);
      auto r = second->read_input(unit, kXPosition, kAnalog1 + 1);
      // A connection that missed an answer would take it for the next one's: start afresh.
      if (!answered(r.exception))
        second = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
      if (r.ok()) {
        ++good_reads;
        for (int address : {kXPosition, kXPosition + 1, kYPosition, kYPosition + 1, kMotion})
          if (r.values[address] != 0)
            wrong(unit, "input register " + std::to_string(address), r.values[address]);
        if (r.values[kAnalog1] != kAnalogOf.at(unit)) wrong(unit, "analog 1", r.values[kAnalog1]);
      }
      // Accelerations written to a unit end in its unit ID: another unit's value shows.
      auto a = second->read_holding(unit, kYAcceleration, 1);
      if (a.ok() && a.values[0] != kFactoryAcceleration && a.values[0] % 10 != unit)
        wrong(unit, "y acceleration", a.values[0]);
    }
  });

  // Each write is unique (a Y acceleration ending in the unit ID), so the journal tells whose
  // reply confirmed what.
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
    wait_until([&] { return client_->read_input(unit, kXPosition, 2).ok(); }, 3s);
    const int value = 1000 + i * 10 + unit;
    writes.push_back({unit, value, client_->write_single(unit, kYAcceleration, value).exception});
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
    char request[32];
    std::snprintf(request, sizeof request, "YA=0%XH\\r", static_cast<unsigned>(w.value));
    const auto it = std::find_if(journal.begin(), journal.end(),
                                 [&](const JournalEntry& e) { return e.request == request; });
    ASSERT_NE(it, journal.end()) << request << " for unit " << w.unit
                                 << " was confirmed but the unit never ran it";
    // Its own confirmation: the M? sent right behind it, answered with the mode, and that answer
    // reached the gateway unharmed.
    const auto confirmation = std::next(it);
    ASSERT_NE(confirmation, journal.end()) << request << " for unit " << w.unit;
    EXPECT_EQ(confirmation->request, "M?\\r") << request << " for unit " << w.unit;
    EXPECT_NE(confirmation->reply.find("M1"), std::string::npos) << confirmation->reply;
    EXPECT_EQ(confirmation->fault, "")
        << request << " for unit " << w.unit << " was confirmed, but the unit's own answer to its "
        << "M? was " << confirmation->fault << ": another reply confirmed it";
  }
  expect_faults_and_confirmed_writes(successes, unknown, writes.size(), journal);
}

INSTANTIATE_TEST_SUITE_P(Interleavings, CententFaultProperty,
                         ::testing::Values(FaultRun{"fast_seed1", false, 1},
                                           FaultRun{"fast_seed2", false, 2},
                                           FaultRun{"wire9600_seed3", true, 3},
                                           FaultRun{"wire9600_seed4", true, 4}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate::test
