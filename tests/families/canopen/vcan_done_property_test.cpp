// Issue 49, "done means arrived" (tests/harness/done_property.hpp) on a kernel vcan0: three CiA
// 402 drives of fieldgate-sim-canopen (nodes 2, 3 and 4) as profile units 21-23 of the daemon's
// CAN bus, driven by moves to the three at once, power cycles of one drive (`power-off ID`, a
// pause, `power-on ID` on the simulator's stdin: boot-up, defaults restored, the position kept)
// while it moves, and home and move before any velocity was written. Every done is checked
// against the simulator's own position actual (`status ID`, pos=; the profile's position is
// 0x6064 in counts, as the model maps it). The gateway sees a power cycle by the node's boot-up
// (drivers/canopen/README.md, "Controller resets"): a move across it ends 0xfffa, never done.
// Runs inside scripts/vcan-run: one daemon, one simulator, one virtual machine boot.
#include <gtest/gtest.h>

#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

#include "done_property.hpp"
#include "harness.hpp"
#include "vcan_fixture.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

const std::map<int, int> kNodeOf = {{21, 2}, {22, 3}, {23, 4}};  // by profile unit

TEST(VcanDoneProperty, EveryDoneStandsAtItsTargetWithNoResetBetween) {
  ASSERT_TRUE(vcan_present());
  ScratchDir dir;
  CanopenSim sim(dir, "2,3,4");
  ASSERT_TRUE(sim.wait_ready()) << "simulator did not start: " << sim.log();

  // Each drive its own node, unit and profile unit. The consumer heartbeat (1 s) is shorter than
  // the longer power cycles below, so those take the node offline before its boot-up.
  std::ostringstream yaml;
  yaml << "modbus:\n  listen: 127.0.0.1:0\n"
       << "models: " FIELDGATE_SOURCE_DIR "/config/models\n"
       << "buses:\n  - name: can\n    protocol: canopen\n"
       << "    can: {interface: " << can_interface() << "}\n"
       << "    timing: {reply_timeout: 500ms, retries: 1, offline_after: 3, probe_interval: 300ms, "
          "heartbeat_timeout: 1s, start_nodes: true}\n"
       << "    nodes:\n";
  for (const auto& [unit, node] : kNodeOf)
    yaml << "      - {name: drive" << node << ", address: " << node
         << ", model: canopen-cia402, unit_id: " << node - 1 << ", profile_unit: " << unit
         << ",\n         limits: {target: {min: -1000000, max: 1000000}}}\n";
  const auto config = dir / "gw.yaml";
  std::ofstream(config) << yaml.str();
  ChildProcess daemon({FIELDGATE_BINARY, "--config", config.string()}, dir / "daemon.log");
  const std::regex listening("modbus: listening on [0-9.]+:([0-9]+)");
  std::smatch m;
  std::string log;
  wait_until(
      [&] {
        log = daemon.log();
        return std::regex_search(log, m, listening) || !daemon.running();
      },
      30s);
  ASSERT_TRUE(std::regex_search(log, m, listening)) << "daemon did not start listening:\n" << log;
  const int port = std::stoi(m[1]);

  DoneProperty property;
  // Single-axis drives: "simultaneous" is every drive on the bus at once; each drive is its own
  // controller, power-cycled alone.
  for (const auto& [unit, node] : kNodeOf) property.axes.push_back({unit, node, node});
  property.device_position = [&](int unit) -> std::optional<int64_t> {
    const std::string node = std::to_string(kNodeOf.at(unit));
    const auto answer = control_line(sim.process(), "status " + node, "node " + node + " ");
    if (!answer) return std::nullopt;
    return field_after(*answer, " pos=");
  };
  // A short power cycle (the heartbeat keeps the node online) and a long one (offline first)
  // in turn. The drive stops where it was; it boots into Switch On Disabled.
  int cycles = 0;
  property.reset = [&](int node) {
    const std::string id = std::to_string(node);
    EXPECT_TRUE(control_line(sim.process(), "power-off " + id, "power-off " + id));
    std::this_thread::sleep_for(cycles++ % 2 ? 1500ms : 150ms);
    EXPECT_TRUE(control_line(sim.process(), "power-on " + id, "power-on " + id));
  };
  // Profile position (sim/canopen/drive402.cpp): trapezoidal at 20,000 counts/s with 50,000
  // counts/s2 up and down, so a 2,000-count move takes 0.4 s, a 15,000-count one 1.15 s (a power
  // cycle 60-400 ms after it was sent finds it well short of its target) and the longest,
  // 60,000 counts, 3.4 s. A drive lands exactly on its target: tolerance 0 (the model's).
  property.min_target = -30000;
  property.max_target = 30000;
  property.min_travel = 2000;
  property.long_travel = 15000;
  property.velocity = 20000;
  property.acceleration = 50000;
  property.power_on = true;  // a drive comes out of a power cycle in Switch On Disabled
  const auto counts = run_done_property(port, daemon, done_seed(1), property);
  // The boot-up is how the gateway sees a power cycle: no other code for a failed command.
  for (const auto& [code, n] : counts.failures)
    EXPECT_EQ(code, kControllerReset) << n << " command(s) failed with 0x" << std::hex << code;

  if (::testing::Test::HasFailure())
    std::cerr << "--- daemon log ---\n" << daemon.log() << "--- simulator log ---\n" << sim.log();
  daemon.terminate();
}

}  // namespace
}  // namespace fieldgate::test
