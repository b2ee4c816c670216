// The modbus_rtu: section: defaults, errors with file:line:column, and the server options and
// broadcast stop writes derived from it.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include "config_file_test.hpp"
#include "gateway/config/config_loader.hpp"
#include "gateway/modbus/modbus_rtu_port.hpp"

namespace fieldgate {
namespace {

namespace fs = std::filesystem;

class ModbusRtuConfigTest : public test::ConfigFileTest {
 protected:
  // Loads the section with two Copley nodes (units 1, 2; the first's axis profile on 21) and a
  // Techno pair (3, 4).
  std::string load(const std::string& rtu, std::optional<LoadedConfig>* out = nullptr) {
    return ConfigFileTest::load(
        rtu +
            "buses:\n"
            "  - name: c\n    protocol: copley-ascii\n"
            "    serial: {device: /dev/null, baud: 115200}\n    nodes:\n"
            "      - {name: a, address: 0, model: copley-amplifier, unit_id: 1,"
            " profile_unit: 21}\n"
            "      - {name: b, address: 3, model: copley-amplifier, unit_id: 2}\n"
            "  - name: t\n    protocol: techno-c\n"
            "    serial: {device: /dev/null, baud: 9600}\n    nodes:\n"
            "      - {name: t0, address: 0, model: techno-c116, unit_id: 3}\n"
            "      - {name: t1, address: 1, model: techno-c116, unit_id: 4}\n",
        out);
  }
};

TEST_F(ModbusRtuConfigTest, DefaultsAreTheSpecs) {
  std::optional<LoadedConfig> c;
  ASSERT_EQ(load("modbus_rtu: {device: /dev/ttyS1}\n", &c), "");
  ASSERT_TRUE(c->gateway.modbus_rtu);
  const auto o = rtu_server_options(*c);
  EXPECT_EQ(o.serial.device, "/dev/ttyS1");
  EXPECT_EQ(o.serial.baud, 19200u);
  EXPECT_EQ(o.serial.parity, 'E');
  EXPECT_EQ(o.silent_interval(), std::chrono::microseconds(2006));  // 3.5 x 11 bits at 19200
  EXPECT_FALSE(o.rs485.enabled);
  EXPECT_EQ(o.slow_writes, modbus::SlowWrites::acknowledge);
  EXPECT_TRUE(o.units.test(1) && o.units.test(4) && !o.units.test(5));
  EXPECT_TRUE(o.units.test(21)) << "a profile unit is served by default";
  EXPECT_TRUE(o.broadcast.writes.empty());
}

TEST_F(ModbusRtuConfigTest, FullSection) {
  std::optional<LoadedConfig> c;
  ASSERT_EQ(load("modbus_rtu:\n  device: /dev/ttyS1\n  baud: 115200\n  parity: none\n"
                 "  stop_bits: 2\n  response_timeout: 300ms\n  slow_writes: silent\n"
                 "  units: [1, 3]\n"
                 "  rs485: {enabled: true, rts_on_send: low, delay_before_send: 2ms,"
                 " delay_after_send: 1ms}\n"
                 "  broadcast_stop: {code: 0x5AA5, actions: {copley-amplifier: abort,"
                 " techno-c116: stop}}\n",
                 &c),
            "");
  const auto o = rtu_server_options(*c);
  EXPECT_EQ(o.serial.baud, 115200u);
  EXPECT_EQ(o.serial.stop_bits, 2u);
  EXPECT_EQ(o.silent_interval(), std::chrono::microseconds(1750));
  EXPECT_EQ(o.response_timeout, std::chrono::milliseconds(300));
  EXPECT_EQ(o.slow_writes, modbus::SlowWrites::silent);
  EXPECT_TRUE(o.rs485.enabled);
  EXPECT_FALSE(o.rs485.rts_high_on_send);
  EXPECT_EQ(o.rs485.delay_before_send, std::chrono::milliseconds(2));
  EXPECT_TRUE(o.units.test(1) && !o.units.test(2) && o.units.test(3) && !o.units.test(4));
  EXPECT_EQ(o.broadcast.value, 0x5AA5);
  EXPECT_EQ(o.broadcast.address, 100);
  // Only served units; abort is Copley's code 6, Techno's stop (code 5) is bus-wide: once.
  ASSERT_EQ(o.broadcast.writes.size(), 2u);
  EXPECT_EQ(o.broadcast.writes[0].unit, 1);
  EXPECT_EQ(o.broadcast.writes[0].value, 6);
  EXPECT_EQ(o.broadcast.writes[1].unit, 3);
  EXPECT_EQ(o.broadcast.writes[1].value, 5);
}

TEST_F(ModbusRtuConfigTest, BusWideStopOncePerBus) {
  std::optional<LoadedConfig> c;
  ASSERT_EQ(
      load("modbus_rtu: {device: /dev/ttyS1, broadcast_stop: {actions: {techno-c116: stop}}}\n",
           &c),
      "");
  const auto o = rtu_server_options(*c);
  ASSERT_EQ(o.broadcast.writes.size(), 1u);
  EXPECT_EQ(o.broadcast.writes[0].unit, 3);
}

TEST_F(ModbusRtuConfigTest, ProfileUnitsCanBeListed) {
  std::optional<LoadedConfig> c;
  ASSERT_EQ(load("modbus_rtu: {device: /dev/ttyS1, units: [2, 21]}\n", &c), "");
  const auto o = rtu_server_options(*c);
  EXPECT_TRUE(o.units.test(21) && o.units.test(2) && !o.units.test(1));
}

TEST_F(ModbusRtuConfigTest, PreciseErrors) {
  // Each listener section, and what its error says.
  const std::pair<std::string, std::string> cases[] = {
      {"modbus_rtu: {device: /dev/ttyS1, baud: 11520}\n",
       "gw.yaml:2:40: error: modbus_rtu baud: 11520 is not a standard rate"},
      {"modbus_rtu: {device: /dev/ttyS1, parity: mark}\n",
       "modbus_rtu parity: expected none, even or odd, found 'mark'"},
      {"modbus_rtu: {device: /dev/ttyS1, data_bits: 7}\n", "Modbus RTU uses 8 data bits"},
      {"modbus_rtu: {device: /dev/ttyS1, response_timeout: 1}\n", "modbus_rtu response_timeout"},
      {"modbus_rtu: {device: /dev/ttyS1, rs485: {delay_before_send: 500us}}\n",
       "the kernel takes whole milliseconds"},
      {"modbus_rtu: {device: /dev/ttyS1, units: [9]}\n",
       "modbus_rtu units: no node on listener default has unit_id 9"},
      {"modbus_rtu: {device: /dev/ttyS1, broadcast_stop: {actions: {copley-amplifier: "
       "halt}}}\n",
       "model copley-amplifier has no action 'halt' (actions: enable"},
      {"modbus_rtu: {device: /dev/ttyS1, slow_writes: wait}\n", "expected acknowledge or silent"},
      {"modbus_rtu: {baud: 9600}\n", "missing required key 'device'"},
      {"modbus_rtu: {device: /dev/ttyS1, speed: 9600}\n", "unknown key 'speed'"},
  };
  for (const auto& [section, expected] : cases) {
    const auto e = load(section);
    EXPECT_NE(e.find(expected), std::string::npos) << section << e;
  }
}

TEST_F(ModbusRtuConfigTest, MapDocumentShowsTheRtuView) {
  std::optional<LoadedConfig> c;
  ASSERT_EQ(load("modbus_rtu: {device: /dev/ttyS1, units: [1, 2], broadcast_stop: {actions: "
                 "{copley-amplifier: abort}}}\n",
                 &c),
            "");
  const std::string text = describe_modbus_rtu(*c);
  EXPECT_NE(text.find("| device | /dev/ttyS1 |"), std::string::npos) << text;
  EXPECT_NE(text.find("| units served | 1, 2 |"), std::string::npos) << text;
  EXPECT_NE(text.find("| 2 | b | copley-amplifier | abort | 6 |"), std::string::npos) << text;
}

}  // namespace
}  // namespace fieldgate
