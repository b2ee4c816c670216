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

#include <cstdio>
#include <map>
#include <string>

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
    SimulatedBus bus = fault_bus("chain", "centent-cn0170",
                                 {FIELDGATE_SIM_CENTENT, "--link", "{link}", "--units", "0,1,2",
                                  "--journal", "{dir}/journal"},
                                 GetParam());
    bus.nodes = nodes();
    start({bus});
    for (const auto& [unit, value] : kAnalogOf)
      plant_->sim().send_line("analog " + std::to_string(unit - 1) + " 1 " + std::to_string(value));
    wait_online(
        {1, 2, 3}, [&](int unit) { return input(unit, kAnalog1) == kAnalogOf.at(unit); }, 20s);
  }
};

TEST_P(CententFaultProperty, NoWriteConfirmedByAnotherReplyAndNoWrongValueServed) {
  FaultProperty property{
      .units = 3, .inputs = {kXPosition, kAnalog1 + 1}, .online = {kXPosition, 2}};
  property.check_read = [](ModbusClient& reader, int unit, const ModbusResult& r,
                           FaultReads& reads) {
    if (r.ok()) {
      for (int address : {kXPosition, kXPosition + 1, kYPosition, kYPosition + 1, kMotion})
        if (r.values[address] != 0)
          reads.wrong_value(unit, "input register " + std::to_string(address), r.values[address]);
      if (r.values[kAnalog1] != kAnalogOf.at(unit))
        reads.wrong_value(unit, "analog 1", r.values[kAnalog1]);
    }
    // Accelerations written to a unit end in its unit ID: another unit's value shows.
    auto a = reader.read_holding(unit, kYAcceleration, 1);
    if (a.ok() && a.values[0] != kFactoryAcceleration && a.values[0] % 10 != unit)
      reads.wrong_value(unit, "y acceleration", a.values[0]);
  };
  // Each write is unique (a Y acceleration ending in the unit ID), so the journal tells whose
  // reply confirmed what.
  property.write = write_unique_values(kYAcceleration);
  property.check_confirmed = [](const FaultWrite& w, const std::vector<JournalEntry>& journal) {
    char request[32];
    std::snprintf(request, sizeof request, "YA=0%XH\\r", static_cast<unsigned>(w.value));
    const auto it = find_request(journal, request);
    ASSERT_NE(it, journal.end()) << request << " for unit " << w.unit
                                 << " was confirmed but the unit never ran it";
    // Its own confirmation: the M? sent right behind it, answered with the mode, and that
    // answer reached the gateway unharmed.
    const auto confirmation = std::next(it);
    ASSERT_NE(confirmation, journal.end()) << request << " for unit " << w.unit;
    EXPECT_EQ(confirmation->request, "M?\\r") << request << " for unit " << w.unit;
    EXPECT_NE(confirmation->reply.find("M1"), std::string::npos) << confirmation->reply;
    EXPECT_EQ(confirmation->fault, "") << request << " for unit " << w.unit
                                       << " was confirmed, but the unit's own answer to its M? was "
                                       << confirmation->fault << ": another reply confirmed it";
  };
  run_fault_property(*plant_, client_, GetParam().seed, property);
}

INSTANTIATE_TEST_SUITE_P(Interleavings, CententFaultProperty,
                         ::testing::ValuesIn(kFastThenSlowRuns), fault_run_name);

}  // namespace
}  // namespace fieldgate::test
