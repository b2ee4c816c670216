// Issue 26, property test: random interleavings of late, dropped, garbled and truncated replies
// around reads and writes, against the Whedco CMC simulator (two CMC-0 units, addresses 4 and 5,
// that execute every line they hear and journal it). Whatever the faults:
//  - every write answered success appears executed in the device journal, answered by its own
//    prompt, and that reply reached the gateway unharmed;
//  - a write the unit refuses (a jog speed below its 200 pp/s minimum: '?') is never answered
//    success;
//  - every value served as good equals the unit's value (each unit's analog input 1 is distinct
//    and constant, the axes stand still, and every V9 written to a unit ends in its unit ID, so
//    a reply taken from another exchange shows).
// In echo and non-echo format (a non-echo reply to a command is a bare prompt, which nothing
// but the order of the line ties to its request), at 115200 baud and at 9600 with wire time.
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "fault_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// config/models/whedco-cmc-xy.yaml
constexpr int kAnalog1 = 3, kXActual = 9, kYActual = 18;  // input registers
constexpr int kXJogSpeed = 6, kV9 = 38;                   // holding, int32

const std::map<int, int> kAddressOf = {{1, 4}, {2, 5}};      // by unit ID
const std::map<int, int> kAnalogOf = {{1, 273}, {2, -546}};  // by unit ID, A/D counts

class WhedcoFaultProperty : public PlantFixture<::testing::TestWithParam<FaultRun>> {
 protected:
  void SetUp() override {
    const FaultRun run = GetParam();
    std::vector<std::string> sim_argv = {
        FIELDGATE_SIM_WHEDCO, "--link",       "{link}", "--units", "4,5", "--axes", "XY",
        "--journal",          "{dir}/journal"};
    if (run.non_echo)
      for (const char* a : {"--non-echo", "all"}) sim_argv.push_back(a);
    SimulatedBus bus = fault_bus("cmc-line", "whedco-cmc", sim_argv, run);
    const std::string suffix = run.non_echo ? "/non-echo" : "";
    for (const auto& [unit, address] : kAddressOf)
      bus.nodes += "      - {name: cmc" + std::to_string(address) + ", address: '" +
                   std::to_string(address) + suffix +
                   "', model: whedco-cmc-xy, unit_id: " + std::to_string(unit) +
                   ", poll: {slow: 300ms, variables: 500ms}}\n";
    start({bus});
    for (const auto& [unit, counts] : kAnalogOf)
      plant_->sim().send_line("analog " + std::to_string(kAddressOf.at(unit)) + " 1 " +
                              std::to_string(counts));
    wait_online(
        {1, 2},
        [&](int unit) {
          auto r = client_->read_input(unit, kAnalog1, 1);
          return r.ok() && static_cast<int16_t>(r.values[0]) == kAnalogOf.at(unit) &&
                 client_->read_holding(unit, kV9, 2).ok();
        },
        30s);
  }
};

TEST_P(WhedcoFaultProperty, NoWriteConfirmedByAnotherReplyAndNoWrongValueServed) {
  FaultProperty property{.units = 2, .inputs = {kAnalog1, 1}, .online = {kAnalog1, 1}};
  property.check_read = [](ModbusClient& reader, int unit, const ModbusResult& a,
                           FaultReads& reads) {
    if (a.ok() && static_cast<int16_t>(a.values[0]) != kAnalogOf.at(unit))
      reads.wrong_value(unit, "analog 1", static_cast<int16_t>(a.values[0]));
    for (int address : {kXActual, kYActual})
      if (const auto p = reader.read_input_i32(unit, address); p && *p != 0)
        reads.wrong_value(unit, "position at input " + std::to_string(address), *p);
    check_ends_in_unit(reader, unit, kV9, "V9", reads);
  };
  // Each write is unique (a V9 value ending in the unit ID, or a jog speed of 100 pp/s, which
  // the unit refuses), so the journal tells whose reply confirmed what.
  property.write = [](ModbusClient& client, int i, int unit, std::mt19937& random) {
    if (random() % 3 == 0)
      return FaultWrite{.refused = true,
                        .exception = client.write_i32(unit, kXJogSpeed, 100).exception};
    const int32_t value = 1000 + i * 10 + unit;
    return FaultWrite{.value = value, .exception = client.write_i32(unit, kV9, value).exception};
  };
  property.refused_confirmed = "a jog speed the unit refuses was confirmed";
  property.check_confirmed = [](const FaultWrite& w, const std::vector<JournalEntry>& journal) {
    // Its own execution, answered by the prompt alone, and that reply reached the
    // gateway unharmed.
    const std::string request =
        std::to_string(kAddressOf.at(w.unit)) + "V9=" + std::to_string(w.value) + "\\r";
    const auto it = find_request(journal, request);
    ASSERT_NE(it, journal.end()) << "V9=" << w.value << " for unit " << w.unit
                                 << " was confirmed but the unit never ran it";
    EXPECT_EQ(it->reply.find('?'), std::string::npos) << it->reply;
    EXPECT_EQ(it->fault, "") << "V9=" << w.value << " for unit " << w.unit
                             << " was confirmed, but the unit's own reply to it was " << it->fault
                             << ": another reply confirmed it";
  };
  run_fault_property(*plant_, client_, GetParam().seed, property);
}

INSTANTIATE_TEST_SUITE_P(Interleavings, WhedcoFaultProperty,
                         ::testing::Values(FaultRun{"fast_echo_seed1", false, 1, false},
                                           FaultRun{"fast_non_echo_seed2", false, 2, true},
                                           FaultRun{"wire9600_non_echo_seed3", true, 3, true},
                                           FaultRun{"wire9600_echo_seed4", true, 4, false}),
                         fault_run_name);

}  // namespace
}  // namespace fieldgate::test
