// The modbus_rtu: section: a Modbus RTU server on a serial port beside the TCP listener.
#pragma once

#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/transport/serial_transport.hpp"
#include "gateway/modbus/rtu_server.hpp"
#include "mapping/diagnostics.hpp"

namespace fieldgate {

class YamlReader;
struct GatewayConfig;

struct ModbusRtuConfig {
  SerialSettings serial;  // parity defaults to even, as the spec does
  bool rs485 = false;
  bool rts_high_on_send = true;
  std::chrono::milliseconds delay_before_send{0};
  std::chrono::milliseconds delay_after_send{0};
  std::chrono::microseconds frame_gap{0};  // 0: t3.5 (1750 us above 19200 baud)
  std::chrono::microseconds incomplete_frame_wait{std::chrono::milliseconds(20)};
  std::chrono::microseconds response_timeout{std::chrono::seconds(1)};
  modbus::SlowWrites slow_writes = modbus::SlowWrites::acknowledge;
  // The listener whose unit-ID space the port serves (index as NodeConfig::listener); 0 is the
  // `modbus:` one.
  std::size_t listener = 0;
  std::vector<uint8_t> units;  // empty: every unit of that listener
  // Broadcast stop: a write of broadcast_code to holding register 100 of unit 0 starts, on
  // every unit served here whose model is listed, that model's stop action.
  uint16_t broadcast_code = 0xFFFF;
  std::map<std::string, std::string> broadcast_actions;  // model name -> action name
  SourceMark mark;
};

// What the general config parser lends this one, so both read serial settings and ${VARS}
// the same way.
struct RtuParseHooks {
  // Reads baud (standard rates unless allowed), data_bits, parity and stop_bits.
  std::function<void(const YAML::Node&, SerialSettings&, const std::string& where)> serial;
  std::function<std::optional<std::string>(const YAML::Node&, std::string_view what)> expand;
};

// Parses the section; errors go to the reader's diagnostics. Needs the buses parsed already
// (unit IDs and models are checked against them); warnings are appended to config.warnings.
std::optional<ModbusRtuConfig> parse_modbus_rtu(YamlReader& reader, const YAML::Node& node,
                                                GatewayConfig& config, const RtuParseHooks& hooks);

}  // namespace fieldgate
