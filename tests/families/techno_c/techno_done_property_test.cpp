// Issue 49, "done means arrived" (tests/harness/done_property.hpp): a Techno C142's axes X, Y
// and Z as profile units 31-33, driven by moves to the three axes at once (the case of the
// issue: each M names every axis), power cycles of the card (the simulator's `power-cycle`:
// axes undefined, motion stopped) while they move, and home and move before any velocity was
// written. Every done is checked against the simulator's own positions (`state`). The card
// answers 4 (axes not defined) to the next command after a power cycle, or never acknowledges
// the capital move it cut short (docs/axis-profile.md).
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

const std::map<int, std::string> kAxisOf = {{31, "x"}, {32, "y"}, {33, "z"}};  // by unit

class TechnoDoneProperty : public PlantTest {
 protected:
  void SetUp() override {
    SimulatedBus bus;
    bus.name = "techno";
    bus.protocol = "techno-c";
    bus.sim_argv = {FIELDGATE_SIM_TECHNO, "--link", "{link}", "--variant", "c142", "--axes", "7"};
    bus.serial = "baud: 19200";
    bus.timing =
        "reply_timeout: 200ms, byte_timeout: 30ms, retries: 1, offline_after: 3, "
        "probe_interval: 300ms";
    bus.nodes =
        "      - {name: c142, address: 0, model: techno-c142, unit_id: 1,\n"
        "         axis_units: {x: 31, y: 32, z: 33}}\n";
    start({bus});
    wait_inputs({31, 32, 33}, 0, 12, 20s);
  }
};

TEST_F(TechnoDoneProperty, EveryDoneStandsAtItsTargetWithNoResetBetween) {
  DoneProperty property;
  property.axes = {{31, 0, 0}, {32, 0, 0}, {33, 0, 0}};
  property.device_position = [&](int unit) -> std::optional<int64_t> {
    const auto answer = control_line(plant_->sim(), "state", "ok state ");
    if (!answer) return std::nullopt;
    return field_after(*answer, " " + kAxisOf.at(unit) + "=");
  };
  property.reset = [&](int) {
    EXPECT_TRUE(control_line(plant_->sim(), "power-cycle", "ok power-cycle"));
  };
  // Behind the home switch (0) is outside the reach. A capital M is acknowledged at its end
  // and the three axes' commands go out one after another: short moves, so that the last
  // write is answered well within the test client's 5 s.
  property.min_target = 0;
  property.max_target = 6000;
  property.min_travel = 300;
  property.long_travel = 3000;
  property.velocity = 8000;  // steps/s
  run_done_property(*plant_, done_seed(1), property);
}

}  // namespace
}  // namespace fieldgate::test
