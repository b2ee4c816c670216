// Issue 49, "done means arrived" (tests/harness/done_property.hpp): two CN0170 units on a daisy
// chain, axes X and Y of each as profile units 21-24, driven by moves to both axes of a unit at
// once, resets of a unit (the simulator's `reset N`: it waits for its auto-baud CR, then
// answers U<n>) while they move, and home and move before any velocity was written. Every done
// is checked against the simulator's own position register (`position N`, 1/1024 step, the
// profile's unit). The gateway sees a reset as the unit's U<n> (the model's reset_count), so a
// move it interrupted ends 0xfffa (docs/axis-profile.md).
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "done_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// By profile unit: the chain's unit number and the axis.
const std::map<int, std::pair<int, std::string>> kAxisOf = {
    {21, {0, "x"}}, {22, {0, "y"}}, {23, {1, "x"}}, {24, {1, "y"}}};

class CententDoneProperty : public PlantTest {
 protected:
  void SetUp() override {
    SimulatedBus bus;
    bus.name = "chain";
    bus.protocol = "centent-cn0170";
    bus.sim_argv = {FIELDGATE_SIM_CENTENT, "--link", "{link}", "--units", "0,1"};
    bus.timing =
        "reply_timeout: 200ms, byte_timeout: 20ms, retries: 1, offline_after: 3, "
        "probe_interval: 300ms";
    bus.nodes =
        "      - {name: table_0, address: 0, model: centent-cn0170, unit_id: 1,\n"
        "         axis_units: {x: 21, y: 22}}\n"
        "      - {name: table_1, address: 1, model: centent-cn0170, unit_id: 2,\n"
        "         axis_units: {x: 23, y: 24}}\n";
    start({bus});
    wait_inputs({21, 22, 23, 24}, 0, 12, 20s);
  }
};

TEST_F(CententDoneProperty, EveryDoneStandsAtItsTargetWithNoResetBetween) {
  DoneProperty property;
  property.axes = {{21, 0, 0}, {22, 0, 0}, {23, 1, 1}, {24, 1, 1}};
  property.device_position = [&](int unit) -> std::optional<int64_t> {
    const auto& [number, axis] = kAxisOf.at(unit);
    const auto answer = control_line(plant_->sim(), "position " + std::to_string(number),
                                     "ok position unit=" + std::to_string(number));
    const auto raw = answer ? field_after(*answer, " " + axis + "=") : std::nullopt;
    if (!raw) return std::nullopt;
    // The simulator prints the 32-bit register unsigned; the gateway reads it signed.
    return static_cast<int32_t>(static_cast<uint32_t>(*raw));
  };
  property.reset = [&](int number) {
    EXPECT_TRUE(control_line(plant_->sim(), "reset " + std::to_string(number),
                             "ok reset " + std::to_string(number)));
  };
  // The position register takes only positive numbers (p.35): targets from 200 steps up.
  property.min_target = 0;
  property.max_target = 6000 * 1024;
  property.min_travel = 200 * 1024;
  property.long_travel = 3000 * 1024;
  property.velocity = 4000;  // steps/s
  run_done_property(*plant_, done_seed(1), property);
}

}  // namespace
}  // namespace fieldgate::test
