#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "drivers/link.hpp"
#include "drivers/protocol_family.hpp"
#include "drivers/transport/serial_transport.hpp"
#include "gateway/config/modbus_rtu_config.hpp"
#include "gateway/modbus/access_control.hpp"
#include "gateway/sparkplug/sparkplug_config.hpp"
#include "mapping/diagnostics.hpp"
#include "mapping/model.hpp"
#include "mapping/register_map.hpp"
#include "mapping/value_type.hpp"

namespace fieldgate {

using std::chrono::microseconds;

enum class OfflineReads { exception, last_value };

struct ModbusConfig {
  std::string address = "0.0.0.0";
  uint16_t port = 502;
  std::size_t max_clients = 32;
  bool evict_when_full = true;              // when_full: evict_idle (true) or refuse
  std::size_t max_clients_per_address = 0;  // 0: no limit
  // New connections per second (a burst of two seconds' worth); 0: no limit.
  std::size_t max_connects_per_second_per_address = 40;
  std::size_t max_connects_per_second = 200;
  microseconds idle_timeout{std::chrono::seconds(300)};
  WordOrder word_order = WordOrder::high_first;
  OfflineReads offline_reads = OfflineReads::exception;
  bool writes_enabled = true;
  microseconds request_timeout{std::chrono::seconds(5)};  // to receive a started request
  ClientAllowList allow;
  std::vector<uint8_t> read_only_units;
  bool read_only_coils = false;
  bool read_only_holding = false;

  bool unit_read_only(uint8_t unit) const;
};

// A further Modbus TCP endpoint with its own unit-ID space 1..247 (`listeners:`); the
// `modbus:` section is the default listener, named "default".
struct ListenerConfig {
  std::string name;
  ModbusConfig modbus;
  SourceMark mark;
};

inline constexpr const char* kDefaultListener = "default";

// When a polled point's value is stale and answered 0x0B instead (`timing: stale_after:`; the
// image's FreshnessPolicy): after `failed_polls` failed polls in a row, or once older than
// `periods` of its poll period, and at least `at_least`.
struct StaleAfter {
  uint32_t failed_polls = 3;
  uint32_t periods = 4;
  microseconds at_least{std::chrono::seconds(2)};
};

struct BusTiming {
  LinkTiming link;
  bool reply_timeout_set = false;  // given in the config (not the default)
  microseconds inter_frame_gap{0};
  microseconds turnaround{std::chrono::milliseconds(1)};  // expected device latency, for the budget
  int retries = 1;
  int offline_after = 3;
  microseconds probe_interval{std::chrono::seconds(2)};
  microseconds reconnect_min{std::chrono::milliseconds(500)};
  microseconds reconnect_max{std::chrono::seconds(10)};
  // CAN buses only. Heartbeat consumer time: a node whose heartbeat (0x700 + ID) stays away
  // this long goes offline; 0 means no heartbeat consumer.
  microseconds heartbeat_timeout{0};
  bool start_nodes = false;  // NMT start for every node at start-up and after its boot-up
  StaleAfter stale_after;
};

struct TransportConfig {
  enum class Kind { serial, tcp, can };
  Kind kind = Kind::serial;
  SerialSettings serial;  // for tcp only baud and framing matter (wire time)
  std::string host;
  uint16_t port = 0;
  std::string can_interface;  // SocketCAN interface name (can0, vcan0)
};

// Installation limits of a writable point, narrower than the model's (travel, speed).
struct WriteLimits {
  std::optional<int64_t> min;
  std::optional<int64_t> max;
};

struct NodeConfig {
  std::string name;
  NodeAddress address;
  ModelPtr model;
  uint8_t unit_id = 0;
  std::map<std::string, microseconds> poll_periods;  // overrides of the model's classes
  std::map<std::string, int64_t> setpoints;          // initial values, overriding defaults
  std::map<std::string, WriteLimits> limits;         // by point or setpoint name
  std::optional<microseconds> reply_timeout;         // overrides the bus's for this node
  std::size_t listener = 0;  // index of GatewayConfig::listener_modbus: 0 is `modbus:`
  StaleAfter stale_after;    // its bus's
  std::map<std::string, uint8_t> axis_units;  // profile axis name -> its unit ID
  SourceMark mark;
  // What the node's values depend on: its bus's protocol and link, its address and its model's
  // text. Equal across a reload: what a replaced bus last read is still this device's.
  std::string identity;

  microseconds period_of(const std::string& poll_class) const;
};

struct BusConfig {
  std::string name;
  std::string protocol;
  FamilyPtr family;
  TransportConfig transport;
  BusTiming timing;
  std::vector<NodeConfig> nodes;
  bool trace = false;  // wire trace on from the start (gateway/bus/wire_trace.hpp)
  // The writes the family makes on its own (gateway/config/device_writes.hpp), each with its
  // switch from `device_writes:` (on unless switched off). The family must leave out those off.
  std::map<std::string, bool> device_writes;
  SourceMark mark;
  // The bus's YAML and the text of the models it uses: equal signatures across a reload mean
  // the bus can keep running untouched.
  std::string signature;
  // The same without the nodes: equal across a reload, the bus may take node changes in place
  // (Bus::reconfigure).
  std::string link_signature;
};

// A node's timing: the bus's, with the node's reply_timeout, or where none is configured (node
// or bus) at least what its family says the node needs (Family::node_timing_need).
LinkTiming node_link_timing(const BusConfig& bus, const NodeConfig& node);

struct MetricsConfig {
  bool enabled = false;
  std::string address = "127.0.0.1";
  uint16_t port = 9502;
  ClientAllowList allow;  // empty: every peer may scrape
};

// The web console (gateway/console): read-only pages of the plant, off unless configured.
// Bound to loopback, any local client may look; bound elsewhere, a client needs an address on
// `allow` and the token whose SHA-256 the token file holds.
struct ConsoleConfig {
  bool enabled = false;
  std::string address = "127.0.0.1";
  uint16_t port = 9580;
  ClientAllowList allow;
  // Connections from one address that have not had a request let in yet; a further one takes
  // the slot of that address's oldest. 0: no limit.
  std::size_t max_pending_per_address = 16;
  std::string token_file;
  std::string token_sha256;  // lower-case hex, read from token_file when the config loads
  bool loopback() const;
};

struct GatewayConfig {
  std::string file;
  ModbusConfig modbus;                    // the default listener
  std::vector<ListenerConfig> listeners;  // further listeners: listener index 1, 2, ...
  MetricsConfig metrics;
  ConsoleConfig console;
  std::optional<ModbusRtuConfig> modbus_rtu;
  sparkplug::SparkplugConfig sparkplug;
  std::vector<std::string> model_dirs;
  std::vector<std::string> protocol_dirs;  // protocol files (docs/protocol-files.md)
  std::vector<BusConfig> buses;
  std::vector<std::string> warnings;  // e.g. poll budgets that cannot be met

  std::size_t listener_count() const { return 1 + listeners.size(); }
  const ModbusConfig& listener_modbus(std::size_t listener) const;
  std::string listener_name(std::size_t listener) const;
  std::optional<std::size_t> find_listener(const std::string& name) const;
  // The nodes served on one listener, with the gateway's global node numbers.
  std::vector<NodeBinding> node_bindings(std::size_t listener = 0) const;
};

}  // namespace fieldgate
