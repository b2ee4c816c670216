// Issue 49, "done means arrived" (tests/harness/done_property.hpp), for a controller described
// by a protocol file whose moves are a set-up then a begin (1D..., then 1GO): the independent
// Parker 6K2 (tests/independent/parker6k_unit.py, written from the manual) run by
// config/protocols/parker-6k.yaml, axes 1 and 2 of one controller as profile units 71-72. Moves
// to both axes at once (the case: axis B's steps ran between axis A's set-up and its
// begin), power cycles of the controller (its control socket's `power-cycle`: drives off, TPC
// 0, back to ECHO1 and COMEXC0) while they move, and home and move before any velocity was
// written. Every done is checked against the unit's own TPC (its control socket's `state`,
// steps). The file names no reset counter: a reset is seen by the position proof (0xffec).
#include <gtest/gtest.h>

#include <regex>
#include <string>
#include <vector>

#include "done_property.hpp"
#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

class Parker6kDoneProperty : public PlantTest {
 protected:
  void SetUp() override {
    SimulatedBus bus;
    bus.name = "parker6k";
    bus.protocol = "parker-6k";
    const std::string unit = FIELDGATE_SOURCE_DIR "/tests/independent/parker6k_unit.py";
    bus.sim_argv = {"/usr/bin/python3", "-B", unit,    "--link", "{link}",
                    "--axes",           "2",  "--log", "none",   "--control",
                    "{dir}/unit.ctl"};
    bus.serial = "baud: 9600";
    bus.timing =
        "reply_timeout: 200ms, byte_timeout: 20ms, retries: 1, offline_after: 3, "
        "probe_interval: 300ms";
    bus.nodes =
        "      - {name: axis_1, address: 1, model: parker-6k, unit_id: 1, profile_unit: 71,\n"
        "         limits: {target: {min: -400000, max: 400000}}}\n"
        "      - {name: axis_2, address: 2, model: parker-6k, unit_id: 2, profile_unit: 72,\n"
        "         limits: {target: {min: -400000, max: 400000}}}\n";
    // Top level, after the modbus section: where the daemon finds the protocol files.
    start({bus}, "protocols: " FIELDGATE_SOURCE_DIR "/config/protocols\n");
    wait_inputs({71, 72}, 0, 12, 20s);
  }
  std::string control() const { return (plant_->dir() / "unit.ctl").string(); }
};

TEST_F(Parker6kDoneProperty, EveryDoneStandsAtItsTargetWithNoResetBetween) {
  DoneProperty property;
  // One controller: its two axes take commands at once and power-cycle together.
  property.axes = {{71, 0, 0}, {72, 0, 0}};
  property.device_position = [&](int unit) -> std::optional<int64_t> {
    const auto answer = unix_socket_request(control(), "state");
    if (!answer) return std::nullopt;
    const std::regex position("\"" + std::to_string(unit - 70) + "\": \\{\"position\": (-?[0-9]+)");
    std::smatch m;
    if (!std::regex_search(*answer, m, position)) return std::nullopt;
    return std::stoll(m[1]);
  };
  property.reset = [&](int) {
    const auto answer = unix_socket_request(control(), "power-cycle");
    EXPECT_TRUE(answer && answer->rfind("ok", 0) == 0) << answer.value_or("no answer");
  };
  property.min_target = -100000;  // steps (25,000 a revolution), within the +-500,000 limits
  property.max_target = 100000;
  property.min_travel = 5000;
  property.long_travel = 60000;
  property.velocity = 20000;       // 0.0001 rev/s: 2 rev/s, 50,000 steps/s
  property.power_on = true;        // drives off at power-up
  property.reset_visible = false;  // nothing on the line shows it: the position proof fails it
  run_done_property(*plant_, done_seed(1), property);
}

}  // namespace
}  // namespace fieldgate::test
