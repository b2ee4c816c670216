#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "config_file_test.hpp"
#include "gateway/config/config_loader.hpp"
#include "text_checks.hpp"

namespace fieldgate {
namespace {

namespace fs = std::filesystem;

class ConfigLoaderTest : public test::ConfigFileTest {
 protected:
  static std::string bus(const std::string& nodes, const std::string& extra = "") {
    return "buses:\n" +
           test::copley_bus_item("b", "{device: /dev/null, baud: 115200}", extra, nodes);
  }
  // The errors of a configuration of bus() alone each name one of `fragments`.
  void expect_bus_errors(std::initializer_list<std::string_view> fragments,
                         const std::string& nodes, const std::string& extra = "") {
    test::expect_contains(load(bus(nodes, extra)), fragments);
  }
};

TEST_F(ConfigLoaderTest, ValidConfigLoads) {
  std::optional<LoadedConfig> c;
  EXPECT_EQ(load(bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n"
                     "      - {name: y, address: 3.b, model: copley-amplifier, unit_id: 2}\n"),
                 &c),
            "");
  ASSERT_TRUE(c);
  ASSERT_EQ(c->gateway.buses.size(), 1u);
  EXPECT_EQ(c->gateway.buses[0].nodes[1].address.text, "3.b");
  EXPECT_TRUE(c->register_map.unit(2));
}

TEST_F(ConfigLoaderTest, UnknownKeyWithLineAndColumn) {
  expect_bus_errors(
      {"gw.yaml:7:19: error: node x: unknown key 'adress'", "missing required key 'address'"},
      "      - {name: x, adress: 0, model: copley-amplifier, unit_id: 1}\n");
}

TEST_F(ConfigLoaderTest, WrongType) {
  expect_bus_errors({"gw.yaml:7:65: error: node x unit_id: expected an integer, found 'one'"},
                    "      - {name: x, address: 0, model: copley-amplifier, unit_id: one}\n");
}

TEST_F(ConfigLoaderTest, DuplicateUnitId) {
  expect_bus_errors({"gw.yaml:8:65: error: node y: unit_id 1 is already used by node x"},
                    "      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n"
                    "      - {name: y, address: 3, model: copley-amplifier, unit_id: 1}\n");
}

TEST_F(ConfigLoaderTest, DuplicateNodeAddress) {
  expect_bus_errors({"gw.yaml:8:28: error: node y: address 3 is already used by node x on bus b"},
                    "      - {name: x, address: 3, model: copley-amplifier, unit_id: 1}\n"
                    "      - {name: y, address: 3, model: copley-amplifier, unit_id: 2}\n");
}

TEST_F(ConfigLoaderTest, AddressOutOfFamilyRange) {
  expect_bus_errors({"gw.yaml:7:28: error: node x address: Copley node ID must be 0..127"},
                    "      - {name: x, address: 128, model: copley-amplifier, unit_id: 1}\n");
}

TEST_F(ConfigLoaderTest, UnknownModelListsKnownOnes) {
  expect_bus_errors({"unknown model 'copley-amp' (models found: ", "copley-amplifier"},
                    "      - {name: x, address: 0, model: copley-amp, unit_id: 1}\n");
}

TEST_F(ConfigLoaderTest, UnknownProtocolListsFamilies) {
  const auto e = load(
      "buses:\n  - name: b\n    protocol: modbus-rtu\n    serial: {device: x}\n"
      "    nodes: []\n");
  test::expect_contains(
      e, {"gw.yaml:4:15: error: bus b: unknown protocol 'modbus-rtu' (known: ", "copley-ascii"});
}

TEST_F(ConfigLoaderTest, UnitIdRange) {
  expect_bus_errors({"unit_id: 0 is out of range 1..247"},
                    "      - {name: x, address: 0, model: copley-amplifier, unit_id: 0}\n");
}

TEST_F(ConfigLoaderTest, BadTiming) {
  expect_bus_errors({"reply_timeout: expected a duration such as 250ms or 2s, found 'soon'",
                     "retries: 20 is out of range 0..10"},
                    "      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n",
                    "    timing: {reply_timeout: soon, retries: 20}\n");
}

TEST_F(ConfigLoaderTest, SerialAndTcpAreExclusive) {
  const auto e = load(
      "buses:\n  - name: b\n    protocol: copley-ascii\n"
      "    nodes:\n      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n");
  test::expect_contains(e, {"needs exactly one of 'serial', 'tcp' or 'can'"});
}

TEST_F(ConfigLoaderTest, SetpointOverrideChecked) {
  expect_bus_errors({"setpoint enable_mode: 5 is out of range 21..31", "has no setpoint 'speed'"},
                    "      - name: x\n        address: 0\n        model: copley-amplifier\n"
                    "        unit_id: 1\n        setpoints: {enable_mode: 5, speed: 3}\n");
}

TEST_F(ConfigLoaderTest, MissingFileIsAnError) {
  Diagnostics d;
  EXPECT_FALSE(load_gateway_config((dir_ / "nope.yaml").string(), d));
  EXPECT_NE(d.to_text().find("cannot open file"), std::string::npos);
}

TEST_F(ConfigLoaderTest, PollBudgetWarning) {
  std::optional<LoadedConfig> c;
  std::string nodes;
  for (int i = 0; i < 10; ++i)
    nodes += "      - {name: n" + std::to_string(i) + ", address: " + std::to_string(i) +
             ", model: copley-amplifier, unit_id: " + std::to_string(i + 1) + "}\n";
  const std::string yaml =
      "buses:\n  - name: slow\n    protocol: copley-ascii\n"
      "    serial: {device: /dev/null, baud: 9600}\n    nodes:\n" +
      nodes;
  EXPECT_EQ(load(yaml, &c), "");
  ASSERT_TRUE(c);
  ASSERT_EQ(c->gateway.warnings.size(), 1u);
  EXPECT_NE(c->gateway.warnings[0].find("bus slow: the configured polls need"), std::string::npos)
      << c->gateway.warnings[0];
}

// --- CAN buses ---------------------------------------------------------------------------------

std::string can_bus(const std::string& transport, const std::string& extra = "",
                    const std::string& protocol = "canopen",
                    const std::string& nodes =
                        "      - {name: a, address: 2, model: canopen-cia402, unit_id: 1}\n") {
  return "buses:\n  - name: c\n    protocol: " + protocol + "\n" + transport + extra +
         "    nodes:\n" + nodes;
}

TEST_F(ConfigLoaderTest, CanBusLoads) {
  std::optional<LoadedConfig> c;
  EXPECT_EQ(load(can_bus("    can: {interface: vcan0}\n",
                         "    timing: {reply_timeout: 20ms, heartbeat_timeout: 500ms, "
                         "start_nodes: true}\n",
                         "canopen",
                         "      - {name: a, address: 2, model: canopen-cia402, unit_id: 1}\n"
                         "      - {name: b, address: 0x7F, model: canopen-cia301, unit_id: 2}\n"),
                 &c),
            "");
  ASSERT_TRUE(c);
  const auto& b = c->gateway.buses.at(0);
  EXPECT_EQ(b.transport.kind, TransportConfig::Kind::can);
  EXPECT_EQ(b.transport.can_interface, "vcan0");
  EXPECT_EQ(b.timing.heartbeat_timeout, std::chrono::milliseconds(500));
  EXPECT_TRUE(b.timing.start_nodes);
  EXPECT_EQ(b.nodes.at(1).address.text, "127");
  EXPECT_TRUE(c->gateway.warnings.empty());
  // Defaults: no heartbeat consumer, nodes left in their NMT state.
  EXPECT_EQ(load(can_bus("    can: {interface: can0}\n"), &c), "");
  EXPECT_EQ(c->gateway.buses.at(0).timing.heartbeat_timeout.count(), 0);
  EXPECT_FALSE(c->gateway.buses.at(0).timing.start_nodes);
}

TEST_F(ConfigLoaderTest, CanInterfaceFromEnvironment) {
  ::setenv("FIELDGATE_TEST_CAN", "can1", 1);
  std::optional<LoadedConfig> c;
  EXPECT_EQ(load(can_bus("    can: {interface: \"${FIELDGATE_TEST_CAN}\"}\n"), &c), "");
  ASSERT_TRUE(c);
  EXPECT_EQ(c->gateway.buses.at(0).transport.can_interface, "can1");
}

TEST_F(ConfigLoaderTest, CanTransportErrors) {
  auto e = load(can_bus("    can: {interface: vcan0}\n    serial: {device: /dev/null}\n"));
  test::expect_contains(
      e, {"gw.yaml:3:5: error: bus c: needs exactly one of 'serial', 'tcp' or 'can'"});
  e = load(can_bus("    can: {interface: vcan0, bitrate: 500000}\n"));
  test::expect_contains(e, {"gw.yaml:5:29: error: bus c can: unknown key 'bitrate'"});
  e = load(can_bus("    can: {}\n"));
  test::expect_contains(e, {"gw.yaml:5:10: error: bus c can: missing required key 'interface'"});
  e = load(can_bus("    can: {interface: \"can 0\"}\n"));
  test::expect_contains(
      e, {"gw.yaml:5:22: error: bus c can interface: 'can 0' is not a network interface "
          "name (such as can0 or vcan0)"});
  e = load(can_bus("    can: {interface: a_very_long_interface_name}\n"));
  test::expect_contains(e, {"is not a network interface name"});
}

TEST_F(ConfigLoaderTest, CanopenAndCanBelongTogether) {
  auto e = load(can_bus("    serial: {device: /dev/null}\n"));
  test::expect_contains(
      e, {"gw.yaml:4:15: error: bus c: protocol canopen runs on a CAN interface: give "
          "can: {interface: can0} instead of serial"});
  e = load(can_bus("    can: {interface: vcan0}\n", "", "copley-ascii",
                   "      - {name: a, address: 2, model: copley-amplifier, unit_id: 1}\n"));
  test::expect_contains(
      e, {"gw.yaml:5:10: error: bus c: a CAN interface carries protocol canopen, not "
          "copley-ascii"});
}

TEST_F(ConfigLoaderTest, CanTimingKeys) {
  auto e = load(bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n",
                    "    timing: {heartbeat_timeout: 1s, start_nodes: true}\n"));
  test::expect_contains(
      e, {"gw.yaml:6:33: error: bus b timing heartbeat_timeout: only a CAN bus (can: ...) "
          "has heartbeats and NMT",
          "gw.yaml:6:50: error: bus b timing start_nodes: only a CAN bus"});
  e = load(can_bus("    can: {interface: vcan0}\n", "    timing: {start_nodes: maybe}\n"));
  test::expect_contains(e,
                        {"gw.yaml:6:27: error: bus c timing start_nodes: expected true or false"});
  e = load(can_bus("    can: {interface: vcan0}\n", "    timing: {heartbeat_timeout: soon}\n"));
  test::expect_contains(e, {"gw.yaml:6:33: error: bus c timing heartbeat_timeout:"});
}

TEST_F(ConfigLoaderTest, CanopenNodeAddresses) {
  auto e = load(can_bus("    can: {interface: vcan0}\n", "", "canopen",
                        "      - {name: a, address: 0, model: canopen-cia402, unit_id: 1}\n"
                        "      - {name: b, address: 128, model: canopen-cia402, unit_id: 2}\n"
                        "      - {name: c, address: 5, model: canopen-cia402, unit_id: 3}\n"
                        "      - {name: d, address: 0x05, model: canopen-cia402, unit_id: 4}\n"));
  test::expect_contains(
      e, {"gw.yaml:7:28: error: node a address: expected a CANopen node ID 1..127, "
          "found '0'",
          "gw.yaml:8:28: error: node b address: expected a CANopen node ID 1..127",
          "gw.yaml:10:28: error: node d: address 5 is already used by node c on bus c"});
}

TEST_F(ConfigLoaderTest, AnUnsetVariableTakesItsFallbackOrIsAnErrorThatNamesTheFallbackSyntax) {
  ::unsetenv("FIELDGATE_TEST_UNSET");
  std::optional<LoadedConfig> c;
  EXPECT_EQ(load("buses:\n  - name: b\n    protocol: copley-ascii\n"
                 "    serial: {device: '${FIELDGATE_TEST_UNSET:-/dev/null}', baud: 115200}\n"
                 "    nodes:\n      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n",
                 &c),
            "");
  ASSERT_TRUE(c);
  EXPECT_EQ(c->gateway.buses[0].transport.serial.device, "/dev/null");
  std::string yaml = bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n");
  yaml.replace(yaml.find("/dev/null"), 9, "'${FIELDGATE_TEST_UNSET}'");
  const auto e = load(yaml);
  test::expect_contains(e, {"environment variable FIELDGATE_TEST_UNSET is not set",
                            "${FIELDGATE_TEST_UNSET:-value}"});
}

TEST_F(ConfigLoaderTest, ASerialDeviceThatIsNotThereIsAWarningNotAnError) {
  std::optional<LoadedConfig> c;
  const std::string yaml =
      bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n");
  const auto at = yaml.find("/dev/null");
  EXPECT_EQ(load(std::string(yaml).replace(at, 9, "/dev/fieldgate-no-such-port"), &c), "");
  ASSERT_TRUE(c);
  ASSERT_EQ(c->gateway.warnings.size(), 1u);
  EXPECT_NE(c->gateway.warnings[0].find(": warning: bus b: serial device "
                                        "/dev/fieldgate-no-such-port does not exist"),
            std::string::npos)
      << c->gateway.warnings[0];
}

TEST_F(ConfigLoaderTest, ShippedDemoConfigIsValid) {
  ::setenv("FIELDGATE_DEMO_DIR", "/tmp", 1);
  Diagnostics d;
  auto c = load_gateway_config(FIELDGATE_SOURCE_DIR "/config/demo.yaml", d);
  EXPECT_TRUE(c) << d.to_text();
}

}  // namespace
}  // namespace fieldgate

namespace fieldgate {
namespace {

// Issue 12 item 4: a node forwarded over CAN must outwait the gateway amplifier's CAN timeout.
TEST_F(ConfigLoaderTest, ForwardedCopleyNodesGetAReplyTimeoutBeyondTheCanTimeout) {
  std::optional<LoadedConfig> c;
  const std::string nodes =
      "      - {name: gw, address: 0, model: copley-amplifier, unit_id: 1}\n"
      "      - {name: fw, address: 3, model: copley-amplifier, unit_id: 2}\n";
  // No reply_timeout configured: the forwarded node's default is derived, no warning.
  ASSERT_EQ(load(bus(nodes, "    timing: {forward_timeout: 200ms}\n"), &c), "");
  const auto& b = c->gateway.buses[0];
  EXPECT_EQ(node_link_timing(b, b.nodes[0]).reply_timeout, std::chrono::milliseconds(100));
  EXPECT_EQ(node_link_timing(b, b.nodes[1]).reply_timeout, std::chrono::milliseconds(250));
  EXPECT_TRUE(c->gateway.warnings.empty());
  // A configured value below it is used, and warned about with the reason.
  ASSERT_EQ(load(bus(nodes, "    timing: {reply_timeout: 50ms}\n"), &c), "");
  const auto& b2 = c->gateway.buses[0];
  EXPECT_EQ(node_link_timing(b2, b2.nodes[1]).reply_timeout, std::chrono::milliseconds(50));
  ASSERT_EQ(c->gateway.warnings.size(), 1u);
  EXPECT_NE(c->gateway.warnings[0].find("node fw: reply_timeout 50 ms is below the 150 ms"),
            std::string::npos)
      << c->gateway.warnings[0];
  EXPECT_NE(c->gateway.warnings[0].find("e 32"), std::string::npos);
  // A per-node reply_timeout that covers it silences the warning for that node only.
  ASSERT_EQ(load(bus("      - {name: gw, address: 0, model: copley-amplifier, unit_id: 1}\n"
                     "      - {name: fw, address: 3, model: copley-amplifier, unit_id: 2, "
                     "reply_timeout: 160ms}\n",
                     "    timing: {reply_timeout: 50ms}\n"),
                 &c),
            "");
  EXPECT_TRUE(c->gateway.warnings.empty());
  EXPECT_EQ(node_link_timing(c->gateway.buses[0], c->gateway.buses[0].nodes[1]).reply_timeout,
            std::chrono::milliseconds(160));
}

// CN0170 options set a whole chain's framing: one chain cannot mix models whose options differ,
// while two chains each with its own options can.
TEST_F(ConfigLoaderTest, CententOptionsAgreeWithinAChainOnly) {
  fs::create_directories(dir_ / "models");
  fs::copy_file(FIELDGATE_SOURCE_DIR "/config/models/centent-cn0170.yaml",
                dir_ / "models/centent-cn0170.yaml");
  {
    std::ifstream in(FIELDGATE_SOURCE_DIR "/config/models/centent-cn0170.yaml");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto at = text.find("model: centent-cn0170");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, std::string("model: centent-cn0170").size(), "model: centent-rts");
    const auto mode = text.find("overflow_mode: warning");
    ASSERT_NE(mode, std::string::npos);
    text.replace(mode, std::string("overflow_mode: warning").size(), "overflow_mode: rts");
    std::ofstream(dir_ / "models/centent-rts.yaml") << text;
  }
  const auto chain = [](const std::string& name, const std::string& device,
                        const std::string& nodes) {
    return "  - name: " + name + "\n    protocol: centent-cn0170\n    serial: {device: " + device +
           ", baud: 9600}\n    nodes:\n" + nodes;
  };
  const auto load_with = [&](const std::string& buses) {
    const auto path = dir_ / "gw.yaml";
    std::ofstream(path) << "models: [models]\nbuses:\n" << buses;
    Diagnostics d;
    (void)load_gateway_config(path.string(), d);
    return d.to_text();
  };
  const std::string mixed =
      load_with(chain("c", "/dev/null",
                      "      - {name: a, address: 0, model: centent-cn0170, unit_id: 1}\n"
                      "      - {name: b, address: 1, model: centent-rts, unit_id: 2}\n"));
  EXPECT_NE(
      mixed.find("node b: model centent-rts's options differ from those of model "
                 "centent-cn0170 (node a), but centent-cn0170 options apply to the whole bus"),
      std::string::npos)
      << mixed;
  EXPECT_EQ(load_with(chain("c1", "/dev/null",
                            "      - {name: a, address: 0, model: centent-cn0170, unit_id: 1}\n") +
                      chain("c2", "/dev/zero",
                            "      - {name: b, address: 0, model: centent-rts, unit_id: 2}\n")),
            "");
}

}  // namespace
}  // namespace fieldgate

namespace fieldgate {
namespace {

// The writes a bus makes to its devices on its own are listed in its configuration, on where
// its settings make the family write at all.
TEST_F(ConfigLoaderTest, DeviceWritesAreListedWithTheirDefaults) {
  std::optional<LoadedConfig> c;
  const std::string node = "      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n";
  ASSERT_EQ(load(bus(node), &c), "");
  EXPECT_EQ(c->gateway.buses.at(0).device_writes,
            (std::map<std::string, bool>{{"baud_switch", true}}));
  ASSERT_EQ(load("buses:\n  - name: b\n    protocol: copley-ascii\n    serial: {device: /dev/null, "
                 "baud: 9600}\n    nodes:\n" +
                     node,
                 &c),
            "");
  EXPECT_EQ(c->gateway.buses.at(0).device_writes.at("baud_switch"), false);  // nothing to switch
  ASSERT_EQ(load(can_bus("    can: {interface: vcan0}\n",
                         "    timing: {heartbeat_timeout: 500ms, start_nodes: true}\n"),
                 &c),
            "");
  EXPECT_EQ(c->gateway.buses.at(0).device_writes,
            (std::map<std::string, bool>{{"heartbeat_producer", true}, {"nmt_start", true}}));
  ASSERT_EQ(load(can_bus("    can: {interface: vcan0}\n"), &c), "");
  EXPECT_EQ(c->gateway.buses.at(0).device_writes,
            (std::map<std::string, bool>{{"heartbeat_producer", false}, {"nmt_start", false}}));
}

TEST_F(ConfigLoaderTest, ASwitchTheFamilyHonoursTurnsTheWriteOff) {
  std::optional<LoadedConfig> c;
  ASSERT_EQ(
      load(can_bus("    can: {interface: vcan0}\n",
                   "    timing: {start_nodes: true}\n    device_writes: {nmt_start: false}\n"),
           &c),
      "");
  EXPECT_FALSE(c->gateway.buses.at(0).timing.start_nodes);
  EXPECT_FALSE(c->gateway.buses.at(0).device_writes.at("nmt_start"));
  const auto e =
      load(can_bus("    can: {interface: vcan0}\n", "    device_writes: {nmt_start: true}\n"));
  test::expect_contains(e, {"nmt_start: true needs timing.start_nodes: true"});
}

// A switch the driver does not honour yet is an error, never a silent promise.
TEST_F(ConfigLoaderTest, ASwitchTheFamilyDoesNotHonourIsRefused) {
  const std::string node = "      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n";
  auto e = load(bus(node, "    device_writes: {baud_switch: false}\n"));
  test::expect_contains(
      e, {"gw.yaml:6:34: error: bus b device_writes: baud_switch: false is not honoured "
          "by the copley-ascii driver of this build"});
  // Where the family would not write anyway, off is simply true.
  EXPECT_EQ(load("buses:\n  - name: b\n    protocol: copley-ascii\n    serial: {device: /dev/null, "
                 "baud: 9600}\n    device_writes: {baud_switch: false}\n    nodes:\n" +
                 node),
            "");
  e = load(bus(node, "    device_writes: {heartbeat_producer: false}\n"));
  test::expect_contains(e,
                        {"'heartbeat_producer' is no write of protocol copley-ascii (its writes: "
                         "baud_switch)"});
  e = load(bus(node, "    device_writes: [baud_switch]\n"));
  test::expect_contains(e, {"bus b device_writes"});
}

}  // namespace
}  // namespace fieldgate
