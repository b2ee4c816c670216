#pragma once

#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "mapping/value_type.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate::sparkplug {

// The `sparkplug:` section: a Sparkplug B edge node publishing every node of the gateway as a
// device. Off unless enabled.
struct SparkplugConfig {
  bool enabled = false;
  std::string host = "127.0.0.1";
  uint16_t port = 1883;
  bool tls = false;  // mqtts:// broker URL
  std::string ca_file;
  std::string cert_file;
  std::string key_file;
  std::string client_id;  // default: fieldgate-<group_id>-<edge_node_id>
  std::string group_id;
  std::string edge_node_id;
  std::string username;
  std::string password;  // read from password_file at load
  std::string password_file;
  std::chrono::microseconds keepalive{std::chrono::seconds(30)};
  std::chrono::microseconds reconnect_min{std::chrono::seconds(1)};
  std::chrono::microseconds reconnect_max{std::chrono::seconds(30)};
  // How often the process image is compared with what was last published (report by exception).
  std::chrono::microseconds scan_interval{std::chrono::milliseconds(100)};
  // Diagnostic counters change with every poll; they are compared this often only.
  std::chrono::microseconds diagnostics_interval{std::chrono::seconds(5)};
  // A change smaller than or equal to the deadband of the point's value type is not published.
  std::map<ValueType, int64_t> deadbands;
  bool commands_enabled = false;
  std::optional<std::string> primary_host_id;

  std::string effective_client_id() const;
  int64_t deadband(ValueType type) const;
  bool operator==(const SparkplugConfig&) const = default;
};

// Parses the section; every problem goes to the reader's diagnostics with file:line:column.
void parse_sparkplug_config(YamlReader& reader, const YAML::Node& node, SparkplugConfig& out);

}  // namespace fieldgate::sparkplug
