#pragma once

// What the serial families' fault property tests (tests/families/*/*_fault_property_test.cpp)
// share: the runs, the bus they run on, the Modbus outcomes a write may have under faults, the
// check that a run was not vacuous, and the run itself (run_fault_property): a second connection
// reads the units in the background while the test writes, under the simulator's chaos, and then
// every value served and every confirmed write is checked. Each family says how to read a unit,
// how to make a write and how its device journal shows a confirmation.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "harness.hpp"

namespace fieldgate::test {

inline constexpr int kTargetFailed = 0x0B, kDeviceFailure = 0x04;
// The test client got no answer within its 5 s (or, on the same connection after one, another
// request's answer): the host was too loaded to run the daemon. No confirmation.
inline constexpr int kNoAnswer = -1;

// A Modbus answer arrived: success, or an exception the gateway sent. Otherwise the connection
// may take a late answer for the next request's, and the test opens a fresh one.
inline bool answered(int exception) {
  return exception >= 0 && exception <= kTargetFailed;
}

// The outcomes a write may have under faults: confirmed, outcome unknown (0x0B), refused by
// the device (0x04), or no answer at the test client.
inline bool expected_write_outcome(int exception) {
  return exception == 0 || exception == kTargetFailed || exception == kDeviceFailure ||
         exception == kNoAnswer;
}

// Not vacuous: faults happened, and writes still got through.
inline void expect_faults_and_confirmed_writes(int successes, int unknown, std::size_t writes,
                                               const std::vector<JournalEntry>& journal) {
  EXPECT_GE(successes, 3) << unknown << " answered 0x0B of " << writes;
  EXPECT_GT(unknown, 0);
  int faulted = 0;
  for (const auto& e : journal) faulted += e.fault.empty() ? 0 : 1;
  EXPECT_GT(faulted, 10);
}

// One parameter of a fault property test.
struct FaultRun {
  const char* name;
  bool slow_wire;  // 9600 baud with wire-time emulation
  unsigned seed;
  bool non_echo = false;  // Whedco: SW2-5 set to non-echo on every unit, configured so
};

// What ctest shows after the name: without it GoogleTest prints the struct's bytes, the
// pointer among them, and the test's ctest name changes with every build.
inline void PrintTo(const FaultRun& run, std::ostream* os) {
  *os << (run.slow_wire ? "9600 baud on an emulated wire" : "115200 baud") << ", seed " << run.seed
      << (run.non_echo ? ", non-echo" : "");
}

inline std::string fault_run_name(const ::testing::TestParamInfo<FaultRun>& info) {
  return info.param.name;
}

// Two runs at full speed, then two at 9600 baud on an emulated wire.
inline const std::vector<FaultRun> kFastThenSlowRuns = {{"fast_seed1", false, 1},
                                                        {"fast_seed2", false, 2},
                                                        {"wire9600_seed3", true, 3},
                                                        {"wire9600_seed4", true, 4}};

// The bus of a run: the simulator (sim_argv) at 115200 baud, or at 9600 with wire-time
// emulation on a slow run, and timing that keeps the nodes online on a bad line.
SimulatedBus fault_bus(std::string name, std::string protocol, std::vector<std::string> sim_argv,
                       const FaultRun& run, const std::string& byte_timeout = "10ms");

// What the background reader found.
struct FaultReads {
  std::atomic<int> good{0}, wrong{0};
  std::string first_wrong;  // the first wrong value, reported by the test

  void wrong_value(const std::string& what, long value) {
    if (wrong++ == 0) first_wrong = what + " " + std::to_string(value);
  }
  void wrong_value(int unit, const std::string& what, long value) {
    wrong_value("unit " + std::to_string(unit) + " " + what, value);
  }
};

// One write of a run and the gateway's answer.
struct FaultWrite {
  int unit = 0;
  int32_t value = 0;     // what tells the write in the journal
  bool refused = false;  // a write the device refuses: never to be answered success
  int exception = 0;
  std::chrono::milliseconds took{0};  // how long the gateway took to answer
};

// A high word first int32 from two registers of a read.
inline int32_t i32_at(const ModbusResult& r, int index) {
  return static_cast<int32_t>((uint32_t{r.values[index]} << 16) | r.values[index + 1]);
}

// Values written to a unit end in its unit ID, so another unit's value shows: reads the int32
// holding registers at `address` of a unit, and a value other than 0 not ending in the unit ID
// is a wrong `what`.
void check_ends_in_unit(ModbusClient& reader, int unit, int address, const std::string& what,
                        FaultReads& reads);

// The first journal line whose request is `request`, or journal.end().
std::vector<JournalEntry>::const_iterator find_request(const std::vector<JournalEntry>& journal,
                                                       const std::string& request);

// Input registers: the first and how many.
struct FaultRegisters {
  int address = 0, count = 1;
};

// What a family's fault property test says of its units, its writes and its journal.
struct FaultProperty {
  int units = 1;  // unit IDs 1 to units, one drawn at random for each read and each write
  // The input registers the reader reads from a unit first (a read that answers success is a
  // good read), and those that show a unit online before a write.
  FaultRegisters inputs{}, online{};
  // A connection that missed an answer may take it for the next request's: when set, the
  // reader and the writer start afresh after one, and a missing answer counts as kNoAnswer.
  // Unset, a missing answer fails the test.
  bool fresh_connection_on_no_answer = true;
  // Checks the first read of a unit (any outcome), and reads more of it through `reader`.
  std::function<void(ModbusClient& reader, int unit, const ModbusResult& inputs, FaultReads&)>
      check_read{};
  // Makes the i-th write (from 1) for a unit; its value, whether refused, and the exception.
  std::function<FaultWrite(ModbusClient& client, int i, int unit, std::mt19937& random)> write{};
  std::string refused_confirmed{};  // the message when a refused write was answered success
  // Checks that the device ran a write answered success, confirmed by its own reply.
  std::function<void(const FaultWrite&, const std::vector<JournalEntry>& journal)>
      check_confirmed{};
};

// A write callback for values unique to a write and a unit: the i-th write for a unit puts
// 1000 + 10 i + unit (a value ending in the unit ID) in a holding register at `address`.
std::function<FaultWrite(ModbusClient&, int, int, std::mt19937&)> write_unique_values(int address);

// The run: chaos on the simulator with the run's seed, the background reader, at least 24
// writes (more until 4 were confirmed, up to 96), chaos off; then no wrong value served, good
// reads, every outcome expected, every confirmed write checked, and faults and confirmations
// both happened. `client` is the test's connection to the daemon, replaced when fresh.
void run_fault_property(Plant& plant, std::unique_ptr<ModbusClient>& client, unsigned seed,
                        const FaultProperty& property);

}  // namespace fieldgate::test
