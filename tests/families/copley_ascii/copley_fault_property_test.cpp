// Issue 12, property tests: random interleavings of late, dropped, garbled and truncated
// replies around writes, against the Copley simulator (which executes every request it hears
// and journals it). Whatever the faults:
//  - every write answered success appears executed, with `ok`, in the device journal;
//  - a write the device refuses (desired state 41, e 14) is never answered success;
//  - every value served as good equals the device's value (each node's inputs are distinct
//    and constant, so a reply taken from the wrong exchange shows).
// At 115200 baud, and at 9600 with wire-time emulation.
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "copley_amplifiers.hpp"
#include "fault_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

constexpr int kDesiredState = 0;     // holding 0 (0x24)
constexpr int kDigitalInputs = 20;   // input register 20 (0xa6)
constexpr int kPositionCommand = 4;  // holding 4-5 (0xca), int32

const std::map<int, uint16_t> kInputs = {{1, 0x11}, {2, 0x22}, {3, 0x44}};   // by unit ID
const std::map<int, std::string> kPrefix = {{1, ""}, {2, "3 "}, {3, "5 "}};  // node prefix

class CopleyFaultProperty : public PlantFixture<::testing::TestWithParam<FaultRun>> {
 protected:
  void SetUp() override {
    SimulatedBus bus = fault_bus("copley", "copley-ascii",
                                 {FIELDGATE_SIM_COPLEY, "--link", "{link}", "--nodes",
                                  kAmplifierAddresses, "--journal", "{dir}/journal"},
                                 GetParam());
    bus.nodes = kAmplifierNodes;
    start({bus});
    plant_->sim().send_line("inputs 0 0x11");
    plant_->sim().send_line("inputs 3 0x22");
    plant_->sim().send_line("inputs 5 0x44");
    wait_online(
        {1, 2, 3},
        [&](int unit) {
          auto r = client_->read_input(unit, kDigitalInputs, 1);
          return r.ok() && r.values[0] == kInputs.at(unit);
        },
        20s);
  }
};

TEST_P(CopleyFaultProperty, NoWriteConfirmedByAnotherReplyAndNoWrongValueServed) {
  FaultProperty property{.units = 3, .inputs = {kDigitalInputs, 1}, .online = {kDigitalInputs, 1}};
  // The reader and the writer keep their connections, and every write is answered.
  property.fresh_connection_on_no_answer = false;
  property.check_read = [](ModbusClient& reader, int unit, const ModbusResult& r,
                           FaultReads& reads) {
    if (r.ok() && r.values[0] != kInputs.at(unit)) reads.wrong_value(unit, "served", r.values[0]);
    auto d = reader.read_holding(unit, kDesiredState, 1);
    if (d.ok() && d.values[0] != 0) reads.wrong_value("desired state", d.values[0]);
    check_ends_in_unit(reader, unit, kPositionCommand, "target", reads);
  };
  // Each write is unique (a distinct target position, or desired state 41 which the device
  // refuses), so the journal tells whose reply confirmed what.
  property.write = [](ModbusClient& client, int i, int unit, std::mt19937& random) {
    if (random() % 3 == 0)
      return FaultWrite{.refused = true,
                        .exception = client.write_single(unit, kDesiredState, 41).exception};
    const int32_t target = i * 10 + unit;
    return FaultWrite{.value = target,
                      .exception = client.write_i32(unit, kPositionCommand, target).exception};
  };
  property.refused_confirmed = "a write the device refuses was confirmed";
  property.check_confirmed = [](const FaultWrite& w, const std::vector<JournalEntry>& journal) {
    // Its own execution, answered ok, and that ok reached the gateway unharmed.
    const std::string request = kPrefix.at(w.unit) + "s r0xca " + std::to_string(w.value) + "\\r";
    const auto it = find_request(journal, request);
    ASSERT_NE(it, journal.end()) << "target " << w.value << " for unit " << w.unit
                                 << " was confirmed but the device never ran it";
    EXPECT_EQ(it->reply, "ok\\r");
    EXPECT_EQ(it->fault, "") << "target " << w.value << " for unit " << w.unit
                             << " was confirmed, but the device's own reply to it was " << it->fault
                             << ": another reply confirmed it";
  };
  run_fault_property(*plant_, client_, GetParam().seed, property);
}

INSTANTIATE_TEST_SUITE_P(Interleavings, CopleyFaultProperty, ::testing::ValuesIn(kFastThenSlowRuns),
                         fault_run_name);

}  // namespace
}  // namespace fieldgate::test
