// Issue 49, "done means arrived" (tests/harness/done_property.hpp): IMS indexers A, B and C on
// one party line as profile units 11-13, driven by moves to all three at once, power cycles of
// the line (the simulator's `reset`: every unit's origin becomes 0) while they move, and home
// and move before any velocity was written. Every done is checked against the simulator's own
// position counter (`status NAME`). Party mode has no sign-on: a reset is seen by the position
// proof alone, so a move it interrupted ends 0xffec (docs/axis-profile.md).
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "done_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

const std::map<int, std::string> kNameOf = {{11, "A"}, {12, "B"}, {13, "C"}};  // by profile unit

class ImsDoneProperty : public PlantTest {
 protected:
  void SetUp() override {
    SimulatedBus bus;
    bus.name = "ims";
    bus.protocol = "ims-party-line";
    bus.sim_argv = {FIELDGATE_SIM_IMS, "--link", "{link}", "--axes", "A,B,C"};
    bus.timing =
        "reply_timeout: 150ms, byte_timeout: 30ms, retries: 1, offline_after: 3, "
        "probe_interval: 300ms";
    for (const auto& [unit, name] : kNameOf)
      bus.nodes += "      - {name: ims_" + name + ", address: " + name +
                   ", model: ims-indexer, unit_id: " + std::to_string(unit - 10) +
                   ", profile_unit: " + std::to_string(unit) + "}\n";
    start({bus});
    wait_inputs({11, 12, 13}, 0, 12, 20s);
  }
};

TEST_F(ImsDoneProperty, EveryDoneStandsAtItsTargetWithNoResetBetween) {
  DoneProperty property;
  // Single-axis units: "simultaneous" is every unit on the line at once; `reset` power-cycles
  // them all.
  property.axes = {{11, 0, 0}, {12, 1, 0}, {13, 2, 0}};
  property.device_position = [&](int unit) -> std::optional<int64_t> {
    const std::string tag = "ok " + kNameOf.at(unit) + " position=";
    const auto answer = control_line(plant_->sim(), "status " + kNameOf.at(unit), tag);
    if (!answer) return std::nullopt;
    return field_after(*answer, tag);
  };
  property.reset = [&](int) { EXPECT_TRUE(control_line(plant_->sim(), "reset", "ok reset")); };
  property.min_target = -7000;
  property.max_target = 7000;
  property.min_travel = 500;
  property.long_travel = 6000;
  property.velocity = 8000;        // steps/s, below the simulator's overrun rate (10,000)
  property.acceleration = 40;      // K: 20,000 steps/s2
  property.reset_visible = false;  // nothing on the line shows it: the position proof fails it
  run_done_property(*plant_, done_seed(1), property);
}

}  // namespace
}  // namespace fieldgate::test
