// 500 nodes on 3 listeners (more than one unit-ID space holds): the generated configuration
// passes `fieldgate check`, and every unit of every listener answers a read of its node.
#include <gtest/gtest.h>

#include <cstdio>
#include <regex>

#include "harness.hpp"

namespace fieldgate::test {
namespace {

constexpr int kBuses = 4, kNodesPerBus = 125, kListeners = 3;
const char* kListenerNames[kListeners] = {"default", "line-b", "line-c"};

// Node k: bus k / 125, Copley address k % 125, listener k % 3, unit k / 3 + 1 (1..167).
std::vector<SimulatedBus> buses() {
  std::vector<SimulatedBus> out;
  for (int b = 0; b < kBuses; ++b) {
    SimulatedBus bus;
    bus.name = "copley" + std::to_string(b);
    bus.protocol = "copley-ascii";
    std::string sim_nodes;
    for (int a = 1; a < kNodesPerBus; ++a) sim_nodes += (a > 1 ? "," : "") + std::to_string(a);
    bus.sim_argv = {FIELDGATE_SIM_COPLEY, "--link", "{link}", "--nodes", sim_nodes};
    for (int a = 0; a < kNodesPerBus; ++a) {
      const int k = b * kNodesPerBus + a;
      bus.nodes += "      - {name: n" + std::to_string(k) + ", address: " + std::to_string(a) +
                   ", model: copley-amplifier, unit_id: " + std::to_string(k / kListeners + 1) +
                   ", listener: " + kListenerNames[k % kListeners] + "}\n";
    }
    out.push_back(std::move(bus));
  }
  return out;
}

std::string run_check(const std::string& config) {
  std::string out;
  FILE* p = ::popen((std::string(FIELDGATE_BINARY) + " check " + config + " 2>&1").c_str(), "r");
  if (!p) return "popen failed";
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, p)) out += buffer;
  ::pclose(p);
  return out;
}

TEST(FiveHundredNodes, CheckPassesAndEveryUnitOfEveryListenerIsServed) {
  Plant plant(buses(),
              "listeners:\n  - {name: line-b, listen: 127.0.0.1:0}\n"
              "  - {name: line-c, listen: 127.0.0.1:0}\n");
  const std::string check = run_check(plant.config_path().string());
  EXPECT_NE(check.find(": ok (4 bus(es), 500 node(s), 500 unit ID(s))"), std::string::npos)
      << check;
  EXPECT_NE(check.find("listener default on 127.0.0.1:0: 167 unit ID(s)"), std::string::npos)
      << check;
  EXPECT_NE(check.find("listener line-c on 127.0.0.1:0: 166 unit ID(s)"), std::string::npos)
      << check;

  std::vector<int> ports{plant.port(), listener_port(plant.daemon(), "line-b"),
                         listener_port(plant.daemon(), "line-c")};
  for (const int port : ports) ASSERT_GT(port, 0) << plant.daemon().log();
  int served = 0;
  for (int l = 0; l < kListeners; ++l) {
    ModbusClient c("127.0.0.1", ports[static_cast<std::size_t>(l)]);
    const int units = l == 2 ? 166 : 167;
    for (int unit = 1; unit <= units; ++unit) {
      // A polled point (not only the diagnostic block): the node behind the unit answered.
      const bool ok =
          wait_until([&] { return c.read_input(unit, 0, 2).ok(); }, std::chrono::seconds(30));
      EXPECT_TRUE(ok) << "listener " << kListenerNames[l] << " unit " << unit;
      served += ok ? 1 : 0;
    }
    EXPECT_EQ(c.read_input(units + 1, 1000, 1).exception, 0x0A)
        << "no node behind unit " << units + 1;
  }
  EXPECT_EQ(served, 500);
}

}  // namespace
}  // namespace fieldgate::test
