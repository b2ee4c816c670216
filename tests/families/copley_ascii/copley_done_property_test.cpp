// Issue 49, "done means arrived" (tests/harness/done_property.hpp): the Copley amplifiers 0, 3
// and 5 as profile units 21-23, driven by moves to all three at once, power cycles of
// amplifiers 3 and 5 (reached over CAN) while they move, and home and move before any velocity
// was written. Every done is checked against the simulator's own motor position (its control
// line's `position N`). A reset is seen by the position proof alone (docs/axis-profile.md): the
// amplifier comes back at 0, disabled, so a move it interrupted ends 0xffec.
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "done_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

const std::map<int, int> kAddressOf = {{21, 0}, {22, 3}, {23, 5}};  // by profile unit

class CopleyDoneProperty : public PlantTest {
 protected:
  void SetUp() override {
    start(std::make_unique<CopleyPlant>(
        "0,3,5",
        "      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1, profile_unit: 21}\n"
        "      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2, profile_unit: 22}\n"
        "      - {name: amp5, address: 5, model: copley-amplifier, unit_id: 3, profile_unit: "
        "23}\n"));
    wait_inputs({21, 22, 23}, 0, 12, 20s);
  }
};

TEST_F(CopleyDoneProperty, EveryDoneStandsAtItsTargetWithNoResetBetween) {
  DoneProperty property;
  // Single-axis amplifiers: "simultaneous" is every amplifier on the line at once. Amplifier
  // 0 keeps the serial link (its reset drops the link to 9600 baud): only 3 and 5 are reset.
  property.axes = {{21, 0, -1}, {22, 3, 3}, {23, 5, 5}};
  property.device_position = [&](int unit) -> std::optional<int64_t> {
    const auto answer = control_line(
        plant_->sim(), "position " + std::to_string(kAddressOf.at(unit)), "ok position ");
    if (!answer) return std::nullopt;
    return field_after(*answer, "ok position " + std::to_string(kAddressOf.at(unit)) + " ");
  };
  property.reset = [&](int address) {
    EXPECT_TRUE(control_line(plant_->sim(), "reset " + std::to_string(address), "ok reset "));
  };
  property.min_target = -25000;
  property.max_target = 25000;
  property.min_travel = 2000;
  property.long_travel = 20000;
  property.velocity = 300000;  // 0.1 counts/s: 30,000 counts/s
  property.power_on = true;
  property.reset_visible = false;  // nothing on the line shows it: the position proof fails it
  run_done_property(*plant_, done_seed(1), property);
}

}  // namespace
}  // namespace fieldgate::test
