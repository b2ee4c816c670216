// Two Modbus listeners, each with its own unit-ID space: the same unit ID reaches a different
// node on each, the allow list is per listener, and a reload keeps an unchanged listener's
// clients.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>

#include "harness.hpp"

namespace fieldgate::test {
namespace {

// amp0 is unit 1 on the default listener, amp3 unit 1 on line-b.
const char* kNodes =
    "      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1}\n"
    "      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 1, listener: line-b}\n";

std::unique_ptr<Plant> plant(const std::string& line_b_extra = "", const std::string& top = "") {
  SimulatedBus bus;
  bus.name = "copley";
  bus.protocol = "copley-ascii";
  bus.sim_argv = {FIELDGATE_SIM_COPLEY, "--link", "{link}", "--nodes", "0,3"};
  bus.nodes = kNodes;
  return std::make_unique<Plant>(
      std::vector<SimulatedBus>{bus},
      top + "listeners:\n  - {name: line-b, listen: 127.0.0.1:0" + line_b_extra + "}\n");
}

// The command's standard output (its warnings go to the test's stderr).
std::string run(const std::string& command) {
  std::string out;
  FILE* p = ::popen(command.c_str(), "r");
  if (!p) return "popen failed";
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, p)) out += buffer;
  ::pclose(p);
  return out;
}

void wait_online(ModbusClient& c, int unit) {
  ASSERT_TRUE(wait_until([&] { return c.read_input(unit, 0, 2).ok(); }));
}

TEST(Listeners, SameUnitIdReachesADifferentNodeOnEachListener) {
  auto p = plant();
  const int port_b = listener_port(p->daemon(), "line-b");
  ASSERT_GT(port_b, 0) << p->daemon().log();
  ASSERT_NE(port_b, p->port());
  ModbusClient a("127.0.0.1", p->port()), b("127.0.0.1", port_b);
  wait_online(a, 1);
  wait_online(b, 1);
  // A confirmed write goes to the controller of the listener's unit 1, and only to it.
  ASSERT_TRUE(a.write_i32(1, 4, 1111).ok());
  ASSERT_TRUE(b.write_i32(1, 4, 2222).ok());
  EXPECT_EQ(a.read_holding(1, 4, 2).values, (std::vector<uint16_t>{0, 1111}));
  EXPECT_EQ(b.read_holding(1, 4, 2).values, (std::vector<uint16_t>{0, 2222}));
  // Unit 2 exists on neither listener: gateway path unavailable.
  EXPECT_EQ(a.read_input(2, 1000, 1).exception, 0x0A);
  EXPECT_EQ(b.read_input(2, 1000, 1).exception, 0x0A);
  // The simulator saw each value at its own node (the poll reads them back).
  ASSERT_TRUE(wait_until([&] {
    const auto va = a.read_holding(1, 4, 2).values, vb = b.read_holding(1, 4, 2).values;
    return va == std::vector<uint16_t>{0, 1111} && vb == std::vector<uint16_t>{0, 2222};
  }));
}

TEST(Listeners, AllowListIsPerListener) {
  auto p = plant(", allow: [10.0.0.0/8]");
  const int port_b = listener_port(p->daemon(), "line-b");
  ASSERT_GT(port_b, 0) << p->daemon().log();
  ModbusClient a("127.0.0.1", p->port()), b("127.0.0.1", port_b);
  EXPECT_TRUE(a.read_input(1, 1000, 1).ok());
  EXPECT_EQ(b.read_input(1, 1000, 1).exception, -1);
  EXPECT_NE(p->daemon().log().find("modbus line-b: refused client 127.0.0.1"), std::string::npos)
      << p->daemon().log();
}

TEST(Listeners, ReloadKeepsAnUnchangedListenersClientsAndOpensANewOne) {
  auto p = plant();
  const int port_b = listener_port(p->daemon(), "line-b");
  ASSERT_GT(port_b, 0) << p->daemon().log();
  ModbusClient a("127.0.0.1", p->port()), b("127.0.0.1", port_b);
  wait_online(a, 1);
  wait_online(b, 1);
  // Add a listener line-c serving amp0 as unit 9 (amp0 moves; line-b is unchanged).
  std::stringstream text;
  text << std::ifstream(p->config_path()).rdbuf();
  std::string config = text.str();
  const std::string line_b = "  - {name: line-b, listen: 127.0.0.1:0}\n";
  config.replace(config.find(line_b), line_b.size(),
                 line_b + "  - {name: line-c, listen: 127.0.0.1:0}\n");
  const std::string amp0 = "model: copley-amplifier, unit_id: 1}";
  config.replace(config.find(amp0), amp0.size(),
                 "model: copley-amplifier, unit_id: 9, listener: line-c}");
  std::ofstream(p->config_path()) << config;
  p->daemon().signal(SIGHUP);
  ASSERT_TRUE(wait_until([&] { return p->daemon().log().find("reloaded:") != std::string::npos; }))
      << p->daemon().log();
  EXPECT_NE(p->daemon().log().find("1 listener(s) opened, 0 closed"), std::string::npos)
      << p->daemon().log();
  const int port_c = listener_port(p->daemon(), "line-c");
  ASSERT_GT(port_c, 0) << p->daemon().log();
  // Same connections (the client does not reconnect), still served once the changed bus has
  // polled again; the default listener has no unit 1 any more.
  EXPECT_TRUE(wait_until([&] { return b.read_input(1, 0, 2).ok(); }));
  EXPECT_EQ(a.read_input(1, 1000, 1).exception, 0x0A);
  ModbusClient c("127.0.0.1", port_c);
  EXPECT_TRUE(wait_until([&] { return c.read_input(9, 0, 2).ok(); }));
}

TEST(Listeners, MetricsPerListener) {
  auto p = plant("", "metrics:\n  listen: 127.0.0.1:0\n");
  const int port_b = listener_port(p->daemon(), "line-b");
  ASSERT_GT(port_b, 0) << p->daemon().log();
  const std::regex listening("metrics: http://127.0.0.1:([0-9]+)/metrics");
  std::smatch m;
  const std::string log = p->daemon().log();
  ASSERT_TRUE(std::regex_search(log, m, listening)) << log;
  ModbusClient b("127.0.0.1", port_b);
  wait_online(b, 1);
  const std::string body = http_get(std::stoi(m[1]), "/metrics");
  EXPECT_NE(body.find("\nfieldgate_modbus_clients{listener=\"line-b\"} 1\n"), std::string::npos)
      << body;
  EXPECT_NE(body.find("\nfieldgate_modbus_clients{listener=\"default\"} 0\n"), std::string::npos);
  EXPECT_NE(body.find("fieldgate_modbus_requests_total{listener=\"line-b\",function=\"4\"}"),
            std::string::npos);
  EXPECT_EQ(body.find("fieldgate_modbus_requests_total{listener=\"default\",function=\"4\"}"),
            std::string::npos);
  EXPECT_NE(
      body.find(
          "fieldgate_node_online{bus=\"copley\",node=\"amp3\",unit=\"1\",listener=\"line-b\"} 1"),
      std::string::npos);
}

TEST(Listeners, CheckAndMapShowEachListener) {
  auto p = plant();
  const std::string config = p->config_path().string();
  const std::string check = run(std::string(FIELDGATE_BINARY) + " check " + config);
  EXPECT_NE(check.find("ok (1 bus(es), 2 node(s), 2 unit ID(s))"), std::string::npos) << check;
  EXPECT_NE(check.find("listener default on 127.0.0.1:0: 1 unit ID(s)"), std::string::npos);
  EXPECT_NE(check.find("listener line-b on 127.0.0.1:0: 1 unit ID(s)"), std::string::npos);
  const std::string md = run(std::string(FIELDGATE_BINARY) + " map " + config);
  const auto a = md.find("# Listener default (127.0.0.1:0)");
  const auto b = md.find("# Listener line-b (127.0.0.1:0)");
  ASSERT_NE(a, std::string::npos) << md;
  ASSERT_NE(b, std::string::npos) << md;
  EXPECT_NE(md.find("## Unit 1: amp0 (bus copley", a), std::string::npos);
  EXPECT_NE(md.find("## Unit 1: amp3 (bus copley", b), std::string::npos);
  const std::string csv = run(std::string(FIELDGATE_BINARY) + " map --format csv " + config);
  EXPECT_EQ(csv.rfind("listener,unit,node,bus,model,", 0), 0u) << csv.substr(0, 200);
  EXPECT_NE(csv.find("\ndefault,1,amp0,copley,copley-amplifier,"), std::string::npos);
  EXPECT_NE(csv.find("\nline-b,1,amp3,copley,copley-amplifier,"), std::string::npos);
}

}  // namespace
}  // namespace fieldgate::test
