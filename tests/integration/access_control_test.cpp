// Access control refused for real over TCP: allow-list, client limit, read-only units and
// tables, per-point write limits and the global writes_enabled switch.
#include <gtest/gtest.h>

#include <memory>
#include <thread>

#include "harness.hpp"

namespace fieldgate::test {
namespace {

const char* kNodes =
    "      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1}\n"
    "      - name: amp3\n        address: 3\n        model: copley-amplifier\n        unit_id: 2\n"
    "        limits: {position_command: {min: 0, max: 1000}, target: {min: -500, max: 500}}\n";

std::unique_ptr<Plant> plant(const std::string& modbus_extra) {
  SimulatedBus bus;
  bus.name = "copley";
  bus.protocol = "copley-ascii";
  bus.sim_argv = {FIELDGATE_SIM_COPLEY, "--link", "{link}", "--nodes", "0,3"};
  bus.nodes = kNodes;
  return std::make_unique<Plant>(std::vector<SimulatedBus>{bus}, modbus_extra);
}

void wait_online(ModbusClient& c, int unit) {
  ASSERT_TRUE(wait_until([&] { return c.read_input(unit, 0, 2).ok(); }));
}

constexpr int kIllegalFunction = 1, kIllegalValue = 3;

TEST(AccessControl, AllowListRefusesOtherClients) {
  auto p = plant("  allow: [10.0.0.0/8, 'fd00::/8']\n");
  ModbusClient c("127.0.0.1", p->port());  // TCP accepts, then the gateway closes
  EXPECT_EQ(c.read_input(1, 1000, 1).exception, -1);
  EXPECT_NE(p->daemon().log().find("refused client 127.0.0.1 (not in the allow list)"),
            std::string::npos);
}

TEST(AccessControl, AllowListAdmitsListedClients) {
  auto p = plant("  allow: ['127.0.0.0/8']\n");
  ModbusClient c("127.0.0.1", p->port());
  EXPECT_TRUE(c.read_input(1, 1000, 1).ok());
}

TEST(AccessControl, MaxClientsRefusesTheExtraConnection) {
  auto p = plant("  max_clients: 2\n  when_full: refuse\n");
  ModbusClient a("127.0.0.1", p->port()), b("127.0.0.1", p->port());
  EXPECT_TRUE(a.read_input(1, 1000, 1).ok());
  EXPECT_TRUE(b.read_input(1, 1000, 1).ok());
  ModbusClient extra("127.0.0.1", p->port());
  EXPECT_EQ(extra.read_input(1, 1000, 1).exception, -1);
  EXPECT_TRUE(a.read_input(1, 1000, 1).ok()) << "existing clients are unaffected";
}

TEST(AccessControl, ReadOnlyUnitAndTables) {
  auto p = plant("  read_only_units: [2]\n");
  ModbusClient c("127.0.0.1", p->port());
  wait_online(c, 2);
  EXPECT_EQ(c.write_single(2, 100, 1).exception, kIllegalFunction);
  EXPECT_EQ(c.write_coil(2, 0, true).exception, kIllegalFunction);
  EXPECT_TRUE(c.read_input(2, 0, 2).ok());
  EXPECT_TRUE(c.write_single(1, 122, 31).ok()) << "other units stay writable";

  auto q = plant("  read_only_tables: [holding_registers]\n");
  ModbusClient d("127.0.0.1", q->port());
  EXPECT_EQ(d.write_single(1, 122, 31).exception, kIllegalFunction);
}

TEST(AccessControl, WriteLimitsRefusedBeforeTheController) {
  auto p = plant("");
  ModbusClient c("127.0.0.1", p->port());
  wait_online(c, 2);
  auto count = [&] {
    auto r = c.read_input(2, 1004, 2);
    return (static_cast<uint32_t>(r.values[0]) << 16) | r.values[1];
  };
  // position_command (holding 4-5 in the Copley model) is limited to 0..1000 on this node.
  const uint32_t before = count();
  EXPECT_EQ(c.write_i32(2, 4, 5000).exception, kIllegalValue);
  EXPECT_EQ(c.write_i32(2, 110, -600).exception, kIllegalValue);  // setpoint target
  // The amplifier never saw the refused value: after a slow poll (1 s) it still reads 0.
  std::this_thread::sleep_for(std::chrono::milliseconds(1300));
  EXPECT_EQ(c.read_holding(2, 4, 2).values, (std::vector<uint16_t>{0, 0}));
  EXPECT_GT(count(), before);
  EXPECT_TRUE(c.write_i32(2, 110, -500).ok());
  EXPECT_TRUE(c.write_i32(2, 4, 1000).ok());
  EXPECT_TRUE(c.write_i32(1, 4, 5000).ok()) << "unit 1 has no such limit";
  EXPECT_EQ(c.read_holding(2, 4, 2).values, (std::vector<uint16_t>{0, 1000}));
}

TEST(AccessControl, WritesDisabledIsMonitorOnly) {
  auto p = plant("  writes_enabled: false\n");
  ModbusClient c("127.0.0.1", p->port());
  wait_online(c, 1);
  EXPECT_EQ(c.write_single(1, 100, 1).exception, kIllegalFunction);  // action
  EXPECT_EQ(c.write_single(1, 0, 21).exception, kIllegalFunction);   // point
  EXPECT_TRUE(c.read_input(1, 0, 2).ok());
}

}  // namespace
}  // namespace fieldgate::test
