// Issue 49, "done means arrived" (tests/harness/done_property.hpp), for a controller described
// by a protocol file: the independent Newport ESP301 (tests/independent/esp301_unit.py, written
// from the manual) run by config/protocols/newport-esp301.yaml, axes 1 and 2 of one controller
// as profile units 61-62. Moves to both axes at once, power cycles of the controller (its
// control socket's `power-cycle`: motors off, positions 0) while they move, and home and move
// before any velocity was written. Every done is checked against the unit's own position (its
// control socket's `state`, mm, the profile's 0.0001 mm). The file names no reset counter: a
// reset is seen by the position proof (0xffec, docs/axis-profile.md).
#include <gtest/gtest.h>

#include <cmath>
#include <regex>
#include <string>
#include <vector>

#include "done_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

class Esp301DoneProperty : public PlantTest {
 protected:
  void SetUp() override {
    SimulatedBus bus;
    bus.name = "esp301";
    bus.protocol = "newport-esp301";
    const std::string unit = FIELDGATE_SOURCE_DIR "/tests/independent/esp301_unit.py";
    bus.sim_argv = {"/usr/bin/python3", "-B",  unit,    "--link", "{link}",
                    "--axes",           "1,2", "--log", "none",   "--control",
                    "{dir}/unit.ctl"};
    bus.serial = "baud: 19200";
    bus.timing =
        "reply_timeout: 200ms, byte_timeout: 20ms, retries: 1, offline_after: 3, "
        "probe_interval: 300ms";
    bus.nodes =
        "      - {name: esp_1, address: 1, model: newport-esp301, unit_id: 1, profile_unit: 61,\n"
        "         limits: {target: {min: -245000, max: 245000}}}\n"
        "      - {name: esp_2, address: 2, model: newport-esp301, unit_id: 2, profile_unit: 62,\n"
        "         limits: {target: {min: -245000, max: 245000}}}\n";
    // Top level, after the modbus section: where the daemon finds the protocol files.
    start({bus}, "protocols: " FIELDGATE_SOURCE_DIR "/config/protocols\n");
    wait_inputs({61, 62}, 0, 12, 20s);
  }
  std::string control() const { return (plant_->dir() / "unit.ctl").string(); }
};

TEST_F(Esp301DoneProperty, EveryDoneStandsAtItsTargetWithNoResetBetween) {
  DoneProperty property;
  // One controller: its two axes take commands at once and power-cycle together.
  property.axes = {{61, 0, 0}, {62, 0, 0}};
  property.device_position = [&](int unit) -> std::optional<int64_t> {
    const auto answer = unix_socket_request(control(), "state");
    if (!answer) return std::nullopt;
    const std::regex position("\"" + std::to_string(unit - 60) +
                              "\": \\{\"position\": ([-0-9.eE+]+)");
    std::smatch m;
    if (!std::regex_search(*answer, m, position)) return std::nullopt;
    return std::llround(std::stod(m[1]) * 10000);
  };
  property.reset = [&](int) {
    const auto answer = unix_socket_request(control(), "power-cycle");
    EXPECT_TRUE(answer && answer->rfind("ok", 0) == 0) << answer.value_or("no answer");
  };
  property.min_target = -60000;  // 0.0001 mm: within the stages' +-25 mm
  property.max_target = 60000;
  property.min_travel = 5000;
  property.long_travel = 40000;
  property.velocity = 50000;       // 5 mm/s, the unit's VU
  property.power_on = true;        // motors off at power-up
  property.reset_visible = false;  // nothing on the line shows it: the position proof fails it
  run_done_property(*plant_, done_seed(1), property);
}

}  // namespace
}  // namespace fieldgate::test
