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

#include <map>
#include <string>

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
    SimulatedBus bus = fault_bus(
        "ims", "ims-party-line",
        {FIELDGATE_SIM_IMS, "--link", "{link}", "--axes", "A,B,C", "--journal", "{dir}/journal"},
        GetParam(), "30ms");
    bus.nodes = kNodes;
    start({bus});
    for (const auto& [unit, name] : kName) {
      plant_->sim().send_line("position " + std::string(1, name) + " " +
                              std::to_string(kPositionOf.at(unit)));
      plant_->sim().send_line("inputs " + std::string(1, name) + " " +
                              std::to_string(kInputsOf.at(unit)));
    }
    wait_online(
        {1, 2, 3},
        [&](int unit) {
          return client_->read_input_i32(unit, kPosition) == kPositionOf.at(unit) &&
                 input(unit, kIo) == kInputsOf.at(unit);
        },
        20s);
  }
};

TEST_P(ImsFaultProperty, NoWriteConfirmedThatDidNotRunAndNoWrongValueServed) {
  FaultProperty property{.units = 3, .inputs = {kPosition, 6}, .online = {kPosition, 2}};
  property.check_read = [](ModbusClient&, int unit, const ModbusResult& r, FaultReads& reads) {
    if (!r.ok()) return;
    const int32_t position = i32_at(r, kPosition);
    if (position != kPositionOf.at(unit)) reads.wrong_value(unit, "position", position);
    if (r.values[kStatus] != 0) reads.wrong_value(unit, "status", r.values[kStatus]);
    if (r.values[kIo] != kInputsOf.at(unit)) reads.wrong_value(unit, "io", r.values[kIo]);
  };
  // Each write is unique (an initial velocity ending in the unit ID), so the journal tells
  // what ran. I changes nothing the polls read.
  property.write = write_unique_values(kInitialVelocity);
  property.check_confirmed = [](const FaultWrite& w, const std::vector<JournalEntry>& journal) {
    const std::string request =
        std::string(1, kName.at(w.unit)) + "I" + std::to_string(w.value) + "\\n";
    EXPECT_NE(find_request(journal, request), journal.end())
        << "I" << w.value << " for unit " << w.unit << " was confirmed but the unit never ran it";
  };
  run_fault_property(*plant_, client_, GetParam().seed, property);
}

INSTANTIATE_TEST_SUITE_P(Interleavings, ImsFaultProperty,
                         ::testing::Values(FaultRun{"wire9600_seed1", true, 1},
                                           FaultRun{"wire9600_seed2", true, 2},
                                           FaultRun{"fast_seed3", false, 3},
                                           FaultRun{"fast_seed4", false, 4}),
                         fault_run_name);

}  // namespace
}  // namespace fieldgate::test
