// Issue 49, "done means arrived" (tests/harness/done_property.hpp): a CMC-0 at address 4, axes
// X and Y as profile units 41-42, driven by moves to both axes at once (the case of the issue:
// X's target was overwritten by Y's command), power cycles of the unit (the simulator's
// `power-cycle 4`: positions 0, Power Failure) while they move, and home and move before any
// velocity was written (the model's FS0 is "no source": such a home is refused with 0x03).
// Every done is checked against the simulator's own position (`position 4 AXIS`). A restarted
// unit reads Power Failure: a controller reset, so a move it interrupted ends 0xfffa
// (docs/axis-profile.md).
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

const std::map<int, std::string> kAxisOf = {{41, "X"}, {42, "Y"}};  // by profile unit

class WhedcoDoneProperty : public PlantTest {
 protected:
  void SetUp() override {
    SimulatedBus bus;
    bus.name = "cmc-line";
    bus.protocol = "whedco-cmc";
    bus.sim_argv = {FIELDGATE_SIM_WHEDCO, "--link", "{link}", "--units", "4", "--axes", "XY"};
    bus.serial = "baud: 38400";
    bus.timing =
        "reply_timeout: 150ms, byte_timeout: 30ms, retries: 1, offline_after: 3, "
        "probe_interval: 300ms";
    bus.nodes =
        "      - {name: cmc_4, address: 4, model: whedco-cmc-xy, unit_id: 1,\n"
        "         axis_units: {x: 41, y: 42}}\n";
    start({bus});
    wait_inputs({41, 42}, 0, 12, 20s);
  }
};

TEST_F(WhedcoDoneProperty, EveryDoneStandsAtItsTargetWithNoResetBetween) {
  DoneProperty property;
  property.axes = {{41, 0, 4}, {42, 0, 4}};
  property.device_position = [&](int unit) -> std::optional<int64_t> {
    const std::string tag = "ok position 4 " + kAxisOf.at(unit) + " ";
    const auto answer = control_line(plant_->sim(), "position 4 " + kAxisOf.at(unit), tag);
    if (!answer) return std::nullopt;
    return field_after(*answer, tag);
  };
  property.reset = [&](int address) {
    EXPECT_TRUE(
        control_line(plant_->sim(), "power-cycle " + std::to_string(address), "ok power-cycle "));
  };
  property.min_target = -100000;
  property.max_target = 100000;
  property.min_travel = 2000;
  property.long_travel = 60000;
  property.max_distance = 65535;  // IMX
  property.velocity = 50000;      // pulses/s
  run_done_property(*plant_, done_seed(1), property);
}

}  // namespace
}  // namespace fieldgate::test
