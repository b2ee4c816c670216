// End to end on a kernel vcan0: the fieldgate daemon with a CAN bus, fieldgate-sim-canopen with
// two CiA 402 drives as they ship (0x1017 = 0) and a second simulator with a device that powers
// up with an error and refuses NMT start while it lasts, a third with a device without the
// optional device name 0x1008 (as canopend ships), a libmodbus client as the PLC and
// candump as the foreign observer. Runs inside scripts/vcan-run; the tests share one plant (one
// virtual machine boot) and run in order.
#include <gtest/gtest.h>

#include <regex>
#include <thread>

#include "gateway/config/config_loader.hpp"
#include "vcan_fixture.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using test::can_interface;
using test::ModbusClient;
using test::wait_until;

constexpr int kModbusDeviceFailure = 0x04;
constexpr int kModbusTargetFailed = 0x0B;

class VcanEndToEnd : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!test::begin_suite(p, "2,3")) return;
    p->faulted_sim = std::make_unique<test::CanopenSim>(
        p->dir, "4", "faulted-sim",
        std::vector<std::string>{"--power-up-error", "0x5000", "--start-needs-no-error"});
    if (!p->faulted_sim->wait_ready()) {
      p->error = "second simulator did not start: " + p->faulted_sim->log();
      return;
    }
    // Without the optional device name 0x1008, as CANopenNode's canopend ships.
    p->nameless_sim = std::make_unique<test::CanopenSim>(
        p->dir, "5", "nameless-sim", std::vector<std::string>{"--no-device-name"});
    if (!p->nameless_sim->wait_ready()) {
      p->error = "third simulator did not start: " + p->nameless_sim->log();
      return;
    }
    const auto config = p->dir / "gw.yaml";
    std::ofstream(config) << "modbus:\n  listen: 127.0.0.1:0\n"
                          << "models: " FIELDGATE_SOURCE_DIR "/config/models\n"
                          << "buses:\n  - name: can\n    protocol: canopen\n"
                          << "    can: {interface: " << can_interface() << "}\n"
                          << "    timing: {reply_timeout: 300ms, retries: 1, offline_after: 3, "
                             "probe_interval: 500ms, heartbeat_timeout: 1s, start_nodes: true}\n"
                          << "    nodes:\n"
                          << "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1, "
                             "poll: {fast: 50ms, identity: 1s}}\n"
                          << "      - {name: axis3, address: 3, model: canopen-cia402, unit_id: 2, "
                             "poll: {fast: 50ms, identity: 1s}}\n"
                          << "      - {name: dev4, address: 4, model: canopen-cia301, unit_id: 3, "
                             "poll: {identity: 1s}}\n"
                          << "      - {name: dev5, address: 5, model: canopen-cia301, unit_id: 4, "
                             "poll: {identity: 1s}}\n";
    Diagnostics d;
    auto loaded = load_gateway_config(config.string(), d);
    if (!loaded) {
      p->error = d.to_text();
      return;
    }
    p->map = std::make_unique<RegisterMap>(loaded->register_map);
    p->daemon = std::make_unique<test::ChildProcess>(
        std::vector<std::string>{FIELDGATE_BINARY, "--config", config.string()},
        p->dir / "daemon.log");
    const std::regex listening("modbus: listening on [0-9.]+:([0-9]+)");
    std::smatch m;
    std::string log;
    wait_until(
        [&] {
          log = p->daemon->log();
          return std::regex_search(log, m, listening) || !p->daemon->running();
        },
        30s);
    if (!std::regex_search(log, m, listening)) {
      p->error = "daemon did not start listening:\n" + log;
      return;
    }
    p->client = std::make_unique<ModbusClient>("127.0.0.1", std::stoi(m[1]));
  }
  static void TearDownTestSuite() {
    delete p;
    p = nullptr;
  }
  void SetUp() override {
    ASSERT_TRUE(test::vcan_present());
    ASSERT_TRUE(test::suite_ready(p));
  }
  void TearDown() override {
    if (HasFailure() && p && p->daemon) std::cerr << "--- daemon log\n" << p->daemon->log();
  }

  // Register address of a named entry of a unit's map (points, setpoints, diag.*).
  static int address(int unit, Table table, const std::string& name) {
    const auto* u = p->map->unit(static_cast<uint8_t>(unit));
    for (const auto& e : u->tables[static_cast<std::size_t>(table)])
      if (e.name == name) return e.address;
    ADD_FAILURE() << "unit " << unit << " has no " << name;
    return 0;
  }
  static std::optional<int64_t> input(int unit, const std::string& name, bool wide = false) {
    const auto r =
        p->client->read_input(unit, address(unit, Table::input_registers, name), wide ? 2 : 1);
    if (!r.ok()) return std::nullopt;
    return wide ? static_cast<int64_t>(
                      static_cast<int32_t>((uint32_t{r.values[0]} << 16) | r.values[1]))
                : r.values[0];
  }
  static int input_exception(int unit, const std::string& name) {
    return p->client->read_input(unit, address(unit, Table::input_registers, name), 1).exception;
  }
  static uint32_t input_u32(int unit, const std::string& name) {
    return static_cast<uint32_t>(input(unit, name, true).value_or(-1));
  }
  static int action(int unit, int code) {
    return p->client->write_single(unit, layout::action_block, static_cast<uint16_t>(code))
        .exception;
  }
  static int action_status(int unit) {
    const auto r = p->client->read_holding(unit, layout::action_block + 1, 2);
    return r.ok() ? r.values[0] : -1;
  }
  static int action_error(int unit) {
    const auto r = p->client->read_holding(unit, layout::action_block + 2, 1);
    return r.ok() ? r.values[0] : -1;
  }
  static bool online(int unit) { return input(unit, "diag.online") == 1; }

  struct Plant : test::VcanSuite {
    std::unique_ptr<test::CanopenSim> faulted_sim;
    std::unique_ptr<test::CanopenSim> nameless_sim;
    std::unique_ptr<RegisterMap> map;
    std::unique_ptr<test::ChildProcess> daemon;
    std::unique_ptr<ModbusClient> client;
    ~Plant() {
      client.reset();
      if (daemon) daemon->terminate();
    }
  };
  static Plant* p;
};

VcanEndToEnd::Plant* VcanEndToEnd::p = nullptr;

TEST_F(VcanEndToEnd, NodesOnlineAndStarted) {
  ASSERT_TRUE(wait_until([] { return online(1) && online(2); }, 30s));
  EXPECT_TRUE(
      wait_until([] { return input(1, "nmt_state") == 5 && input(2, "nmt_state") == 5; }, 10s));
  EXPECT_GE(p->candump->count("000#0102"), 1u);
  EXPECT_GE(p->candump->count("000#0103"), 1u);
  EXPECT_TRUE(wait_until([] { return input_u32(1, "vendor_id") == 0x00F1E1D6u; }));
  EXPECT_TRUE(wait_until([] { return input_u32(2, "serial_number") == 0x51000003u; }));
}

TEST_F(VcanEndToEnd, HeartbeatProducerConfiguredBeforeStartNoFlapping) {
  ASSERT_TRUE(wait_until([] { return online(1) && online(2); }, 30s));
  // heartbeat_timeout 1s: 333 ms (0x014D) written to 0x1017 of each node, before its NMT start.
  for (const char* node : {"2", "3"}) {
    const auto frames = p->candump->frames();
    const auto first = [&](const std::string& pattern) {
      const std::regex re(pattern);
      for (std::size_t i = 0; i < frames.size(); ++i)
        if (std::regex_match(frames[i], re)) return i;
      return frames.size();
    };
    const auto write = first(std::string("60") + node + "#2B1710004D010000");
    EXPECT_LT(write, frames.size()) << node << "\n" << p->candump->text();
    EXPECT_LT(write, first(std::string("000#010") + node)) << node;
  }
  const auto mark = p->candump->size();
  std::this_thread::sleep_for(3s);
  EXPECT_GE(p->candump->count("702#05", mark), 6u) << p->candump->text(mark);
  EXPECT_TRUE(online(1) && online(2));
  const auto log = p->daemon->log();
  EXPECT_EQ(log.find("node axis2 (2) offline"), std::string::npos) << log;
  EXPECT_EQ(log.find("node axis3 (3) offline"), std::string::npos) << log;
  EXPECT_NE(log.find("node axis2 (2) heartbeat producer time 0x1017 set to 333 ms (consumer "
                     "1000 ms)"),
            std::string::npos)
      << log;
}

TEST_F(VcanEndToEnd, EveryIdentityPointIsRead) {
  // The identity class (1 s here) runs in full: nothing keeps answering 0x0B.
  for (int unit : {1, 2})
    for (const char* name : {"vendor_id", "product_code", "serial_number"})
      EXPECT_TRUE(wait_until([&] { return input(unit, name, true).has_value(); }, 5s))
          << "unit " << unit << " " << name;
  const auto heartbeat = address(1, Table::holding_registers, "heartbeat_time");
  EXPECT_EQ(p->client->read_holding(1, heartbeat, 1).values.at(0), 333);
}

TEST_F(VcanEndToEnd, NodeStayingPreOperationalIsReported) {
  ASSERT_TRUE(wait_until([] { return online(3); }, 30s));
  EXPECT_TRUE(wait_until([] { return input(3, "nmt_state") == 127; }, 10s));
  EXPECT_TRUE(wait_until([] { return input(3, "error_register") == 0x01; }, 10s));
  EXPECT_TRUE(wait_until(
      [] {
        return p->daemon->log().find(
                   "node dev4 (4) stays pre-operational after NMT start; error "
                   "register 0x01 (generic)") != std::string::npos;
      },
      10s))
      << p->daemon->log();
  std::this_thread::sleep_for(3s);
  EXPECT_EQ(p->candump->count("000#0104"), 1u) << "started again and again";
  EXPECT_TRUE(online(3));
}

TEST_F(VcanEndToEnd, ExpeditedWriteOfAPointExactFrames) {
  const auto mark = p->candump->size();
  const auto addr = address(1, Table::holding_registers, "heartbeat_time");
  ASSERT_TRUE(p->client->write_single(1, addr, 150).ok());
  EXPECT_TRUE(wait_until([&] {
    return p->candump->count("602#2B17100096000000", mark) == 1 &&
           p->candump->count("582#6017100000000000", mark) >= 1;
  })) << p->candump->text(mark);
  EXPECT_EQ(p->client->read_holding(1, addr, 1).values.at(0), 150);
}

TEST_F(VcanEndToEnd, DeviceWithoutDeviceNameIsReadInOneRequest) {
  ASSERT_TRUE(wait_until([] { return online(4); }, 30s));
  // Input registers 0-31, every read-only point of canopen-cia301, in one request as a PLC reads
  // them: the absent 0x1008 reads as the empty name instead of failing the read with 0x0B.
  EXPECT_TRUE(wait_until([] { return p->client->read_input(4, 0, 32).ok(); }, 10s))
      << p->daemon->log();
  const auto name = address(4, Table::input_registers, "device_name_0");
  const auto r = p->client->read_input(4, name, 16);
  ASSERT_TRUE(r.ok());
  for (const auto v : r.values) EXPECT_EQ(v, 0);
  EXPECT_NE(input_u32(4, "diag.data_age"), 0xffffffffu);
  std::this_thread::sleep_for(3s);  // three identity periods
  EXPECT_EQ(p->candump->count("605#4008100000000000"), 1u) << "absent, yet polled again";
  EXPECT_EQ(input_u32(4, "sdo_abort_code"), 0u);
  EXPECT_EQ(input_u32(4, "diag.last_device_error_code"), 0u);
  EXPECT_NE(p->daemon->log().find("node 5: no object 0x1008:0 (SDO abort 0x06020000"),
            std::string::npos)
      << p->daemon->log();
}

TEST_F(VcanEndToEnd, AbortIsException04WithTheCodeReadable) {
  const auto mode = address(1, Table::holding_registers, "modes_of_operation");
  const auto r = p->client->write_single(1, mode, 3);  // profile velocity: not in the simulator
  EXPECT_EQ(r.exception, kModbusDeviceFailure);
  EXPECT_TRUE(wait_until([] { return input_u32(1, "sdo_abort_code") == 0x06090030u; }));
  // The diagnostic block has the whole code; its 16-bit register says it is wider.
  EXPECT_EQ(input_u32(1, "diag.last_device_error_code"), 0x06090030u);
  EXPECT_EQ(input(1, "diag.last_device_error"), 0xffff);
  EXPECT_TRUE(wait_until([] { return p->candump->count("582#8060600030000906") >= 1; }))
      << p->candump->text();
  EXPECT_TRUE(online(1));  // an abort is an answer
}

TEST_F(VcanEndToEnd, PdoPointsUpdateWithoutSdo) {
  const auto mark = p->candump->size();
  std::this_thread::sleep_for(2s);
  EXPECT_GE(p->candump->count("182#.*", mark), 5u);
  EXPECT_EQ(p->candump->count("60[23]#4041600000000000", mark), 0u);
  EXPECT_EQ(p->candump->count("60[23]#4064600000000000", mark), 0u);
  EXPECT_GE(p->candump->count("602#406C600000000000", mark), 5u);  // SDO-polled velocity
  EXPECT_EQ(input(1, "statusword").value_or(0) & 0x4F, 0x40);
}

TEST_F(VcanEndToEnd, EnableAndMoveAbsolute) {
  const auto before_enable = p->candump->size();
  ASSERT_EQ(action(1, 1), 0) << "enable";
  EXPECT_EQ(action_status(1), 2);
  ASSERT_TRUE(wait_until([] { return (input(1, "statusword").value_or(0) & 0x6F) == 0x27; }));
  // candump is another process and may print the enable's last controlword after the daemon has
  // seen its effect: mark the move's frames only once candump has caught up with the enable.
  ASSERT_TRUE(wait_until([&] {
    return p->candump->count("602#2B4060000F000000", before_enable) >= 1;
  })) << p->candump->text();
  const auto target = address(1, Table::holding_registers, "target");
  ASSERT_TRUE(p->client->write_i32(1, target, 4000).ok());
  const auto velocity = address(1, Table::holding_registers, "velocity");
  ASSERT_TRUE(p->client->write_i32(1, velocity, 20000).ok());
  const auto mark = p->candump->size();
  ASSERT_EQ(action(1, 3), 0) << "move_absolute";
  ASSERT_TRUE(wait_until([] { return action_status(1) == 2; }, 30s))
      << "action status " << action_status(1) << " error " << action_error(1);
  EXPECT_EQ(input(1, "position_actual", true), 4000);
  EXPECT_EQ(input(1, "statusword").value_or(0) & 0x0400, 0x0400);  // target reached
  // The new-setpoint handshake on the wire: target, bit 4 rising with bit 5, bit 4 down.
  const auto f = p->candump->frames();
  std::vector<std::string> cw;
  for (std::size_t i = mark; i < f.size(); ++i)
    if (f[i].rfind("602#2B406000", 0) == 0 || f[i].rfind("602#237A6000", 0) == 0)
      cw.push_back(f[i]);
  EXPECT_EQ(cw, (std::vector<std::string>{"602#237A6000A00F0000", "602#2B4060002F000000",
                                          "602#2B4060003F000000", "602#2B4060002F000000"}));
  // The position came by TPDO while moving, not by SDO.
  EXPECT_EQ(p->candump->count("602#4064600000000000", mark), 0u);
  EXPECT_GE(p->candump->count("182#37[0-9A-F]{2}[0-9A-F]{8}", mark), 3u);
}

TEST_F(VcanEndToEnd, EmergencySurfaces) {
  p->sim->command("fault 2 0x2310");
  ASSERT_TRUE(wait_until([] { return input(1, "emcy_code") == 0x2310; }));
  EXPECT_EQ(input(1, "emcy_error_register"), 0x03);
  EXPECT_EQ(input(1, "diag.last_device_error"), 0x2310);
  EXPECT_TRUE(wait_until([] { return (input(1, "statusword").value_or(0) & 0x08) != 0; }));
  // candump may log it after the daemon served it.
  EXPECT_TRUE(wait_until([] { return p->candump->count("082#1023030000000000") >= 1; }))
      << p->candump->text();
  ASSERT_EQ(action(1, 7), 0) << "fault_reset";
  EXPECT_TRUE(wait_until([] { return input(1, "emcy_code") == 0; }));
  EXPECT_TRUE(wait_until([] { return (input(1, "statusword").value_or(0) & 0x4F) == 0x40; }));
  EXPECT_EQ(input(1, "diag.last_device_error"), 0x2310);  // the last error stays readable
}

TEST_F(VcanEndToEnd, HeartbeatLossIsOfflineAndBack) {
  ASSERT_TRUE(online(2));
  p->sim->command("power-off 3");
  ASSERT_TRUE(wait_until([] { return input(2, "diag.online") == 0; }, 20s));
  EXPECT_EQ(input_exception(2, "position_actual"), kModbusTargetFailed);
  EXPECT_EQ(action(2, 1), kModbusTargetFailed);
  EXPECT_TRUE(online(1));
  const auto mark = p->candump->size();
  p->sim->command("power-on 3");
  ASSERT_TRUE(wait_until([] { return online(2); }, 20s));
  EXPECT_TRUE(wait_until([] { return input(2, "nmt_state") == 5; }));
  EXPECT_GE(p->candump->count("703#00", mark), 1u);
  EXPECT_GE(p->candump->count("000#0103", mark), 1u);
  EXPECT_TRUE(input(2, "position_actual", true).has_value());
}

}  // namespace
}  // namespace fieldgate
