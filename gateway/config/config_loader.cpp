#include "gateway/config/config_loader.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

#include <boost/asio/ip/address.hpp>

#include "drivers/protocol_file/protocol_file_family.hpp"
#include "drivers/protocol_file/protocol_loader.hpp"
#include "gateway/bus/poll_budget.hpp"
#include "gateway/config/device_writes.hpp"
#include "gateway/config/modbus_rtu_config.hpp"
#include "gateway/console/console_access.hpp"
#include "gateway/sparkplug/sparkplug_config.hpp"
#include "mapping/model_loader.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate {

bool ModbusConfig::unit_read_only(uint8_t unit) const {
  for (const auto u : read_only_units)
    if (u == unit) return true;
  return false;
}

bool ConsoleConfig::loopback() const {
  boost::system::error_code ec;
  const auto a = asio::ip::make_address(address, ec);
  return !ec && a.is_loopback();
}

microseconds NodeConfig::period_of(const std::string& poll_class) const {
  if (const auto it = poll_periods.find(poll_class); it != poll_periods.end()) return it->second;
  if (const auto* c = model->find_poll_class(poll_class)) return c->period;
  return microseconds{0};
}

LinkTiming node_link_timing(const BusConfig& bus, const NodeConfig& node) {
  LinkTiming t = bus.timing.link;
  if (node.reply_timeout) {
    t.reply_timeout = *node.reply_timeout;
  } else if (!bus.timing.reply_timeout_set && bus.family) {
    const auto need = bus.family->node_timing_need(node.address, t);
    t.reply_timeout = std::max(t.reply_timeout, need.reply_timeout);
  }
  return t;
}

const ModbusConfig& GatewayConfig::listener_modbus(std::size_t listener) const {
  return listener == 0 ? modbus : listeners.at(listener - 1).modbus;
}

std::string GatewayConfig::listener_name(std::size_t listener) const {
  return listener == 0 ? std::string(kDefaultListener) : listeners.at(listener - 1).name;
}

std::optional<std::size_t> GatewayConfig::find_listener(const std::string& name) const {
  for (std::size_t i = 0; i < listener_count(); ++i)
    if (listener_name(i) == name) return i;
  return std::nullopt;
}

std::vector<NodeBinding> GatewayConfig::node_bindings(std::size_t listener) const {
  std::vector<NodeBinding> bindings;
  int index = 0;
  for (const auto& bus : buses)
    for (const auto& node : bus.nodes) {
      if (node.listener == listener)
        bindings.push_back({node.unit_id, index, node.name, bus.name, node.model});
      ++index;
    }
  return bindings;
}

namespace {

namespace fs = std::filesystem;

class ConfigParser {
 public:
  ConfigParser(YamlReader& reader) : r_(reader) {}

  std::optional<GatewayConfig> parse(const YAML::Node& root) {
    if (!root.IsDefined()) return std::nullopt;
    if (!r_.expect_map(root, "gateway configuration")) return std::nullopt;
    r_.reject_unknown_keys(root,
                           {"modbus", "listeners", "modbus_rtu", "metrics", "console", "models",
                            "protocols", "buses", "sparkplug"},
                           "gateway configuration");
    GatewayConfig config;
    config.file = r_.file();
    if (root["modbus"]) parse_modbus(root["modbus"], config.modbus, "modbus");
    listener_marks_.push_back(root["modbus"] ? r_.mark(root["modbus"]) : r_.mark(root));
    if (const auto listeners = root["listeners"];
        listeners && r_.expect_sequence(listeners, "listeners"))
      for (const auto& l : listeners) parse_listener(l, config);
    if (root["metrics"]) parse_metrics(root["metrics"], config.metrics);
    if (root["console"]) parse_console(root["console"], config.console);
    if (root["sparkplug"])
      sparkplug::parse_sparkplug_config(r_, root["sparkplug"], config.sparkplug);
    parse_model_dirs(root["models"], config);
    for (const auto& dir : config.model_dirs) library_.load_directory(dir, r_.diagnostics());
    parse_protocol_dirs(root["protocols"], config);
    for (const auto& dir : config.protocol_dirs) protocols_.load_directory(dir, r_.diagnostics());
    if (auto buses = r_.require(root, "buses", "gateway configuration");
        buses && r_.expect_sequence(*buses, "buses")) {
      for (const auto& bus : *buses) parse_bus(bus, config);
    }
    if (root["modbus_rtu"])
      config.modbus_rtu = parse_modbus_rtu(
          r_, root["modbus_rtu"], config,
          {[this](const YAML::Node& n, SerialSettings& s, const std::string& w) {
             parse_serial(n, s, w, false);
           },
           [this](const YAML::Node& n, std::string_view what) { return expand(n, what); }});
    return config;
  }

 private:
  // ${NAME} is replaced by the environment variable, so one config serves several machines.
  std::optional<std::string> expand(const YAML::Node& node, std::string_view what) {
    auto text = r_.string(node, what);
    if (!text) return std::nullopt;
    std::string out;
    for (size_t i = 0; i < text->size(); ++i) {
      if ((*text)[i] == '$' && i + 1 < text->size() && (*text)[i + 1] == '{') {
        const auto close = text->find('}', i);
        if (close == std::string::npos) {
          r_.error(node, fmt::format("{}: unterminated ${{ in '{}'", what, *text));
          return std::nullopt;
        }
        // ${NAME:-fallback}, as in the shell: the fallback when NAME is unset or empty.
        std::string name = text->substr(i + 2, close - i - 2);
        std::optional<std::string> fallback;
        if (const auto dash = name.find(":-"); dash != std::string::npos) {
          fallback = name.substr(dash + 2);
          name.resize(dash);
        }
        const char* value = std::getenv(name.c_str());
        if (value && *value) {
          out += value;
        } else if (fallback) {
          out += *fallback;
        } else {
          r_.error(node, fmt::format("{}: environment variable {} is not set (a fallback: "
                                     "${{{}:-value}})",
                                     what, name, name));
          return std::nullopt;
        }
        i = close;
      } else {
        out += (*text)[i];
      }
    }
    return out;
  }

  // ADDRESS:PORT or [IPv6]:PORT; port 0 means any free port (the daemon logs the one it got).
  void parse_listen(const YAML::Node& listen, const std::string& what, std::string& address,
                    uint16_t& port_out) {
    auto text = r_.string(listen, what);
    if (!text) return;
    const auto colon = text->rfind(':');
    std::optional<int64_t> port;
    if (colon != std::string::npos) port = parse_integer_text(text->substr(colon + 1));
    std::string host = colon == std::string::npos ? *text : text->substr(0, colon);
    if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
      host = host.substr(1, host.size() - 2);
    boost::system::error_code ec;
    if (!host.empty()) asio::ip::make_address(host, ec);
    if (!port || *port < 0 || *port > 65535 || ec) {
      r_.error(listen, fmt::format("{}: expected ADDRESS:PORT such as 127.0.0.1:1502 or "
                                   "[::]:502, found '{}'",
                                   what, *text));
      return;
    }
    address = host.empty() ? "0.0.0.0" : host;
    port_out = static_cast<uint16_t>(*port);
  }

  void parse_listener(const YAML::Node& node, GatewayConfig& config) {
    if (!r_.expect_map(node, "listener")) return;
    ListenerConfig l;
    l.mark = r_.mark(node);
    std::string where = "listener";
    if (auto n = r_.require(node, "name", where))
      if (auto s = r_.string(*n, "listener name")) {
        l.name = *s;
        where = "listener " + *s;
        if (config.find_listener(*s))
          r_.error(*n, fmt::format("{}: listener name is already used{}", where,
                                   *s == kDefaultListener ? " (by the modbus: section)" : ""));
      }
    if (!r_.require(node, "listen", where)) return;
    parse_modbus(node, l.modbus, where, true);
    for (std::size_t i = 0; i < config.listener_count(); ++i) {
      const auto& other = config.listener_modbus(i);
      if (other.port != l.modbus.port || l.modbus.port == 0) continue;
      const auto unspecified = [](const std::string& a) { return a == "0.0.0.0" || a == "::"; };
      if (other.address == l.modbus.address || unspecified(other.address) ||
          unspecified(l.modbus.address))
        r_.error(node["listen"],
                 fmt::format("{}: {}:{} overlaps listener {} ({}:{}, {})", where, l.modbus.address,
                             l.modbus.port, config.listener_name(i), other.address, other.port,
                             to_string(listener_marks_[i])));
    }
    listener_marks_.push_back(l.mark);
    config.listeners.push_back(std::move(l));
  }

  // A node's listener: its own `listener:` key, else its bus's, else the default.
  std::size_t resolve_listener(const YAML::Node& key, const GatewayConfig& config,
                               const std::string& where, std::size_t fallback) {
    if (!key) return fallback;
    const auto name = r_.string(key, where + " listener");
    if (!name) return fallback;
    if (const auto i = config.find_listener(*name)) return *i;
    std::string known;
    for (std::size_t i = 0; i < config.listener_count(); ++i)
      known += (known.empty() ? "" : ", ") + config.listener_name(i);
    r_.error(key, fmt::format("{}: unknown listener '{}' (listeners: {})", where, *name, known));
    return fallback;
  }

  void parse_metrics(const YAML::Node& node, MetricsConfig& m) {
    if (!r_.expect_map(node, "metrics")) return;
    r_.reject_unknown_keys(node, {"listen", "enabled", "allow"}, "metrics");
    m.enabled = true;
    if (node["enabled"]) m.enabled = r_.boolean(node["enabled"], "metrics enabled").value_or(true);
    if (node["listen"]) parse_listen(node["listen"], "metrics listen", m.address, m.port);
    if (const auto allow = node["allow"]) m.allow = parse_allow(allow, "metrics");
  }

  void parse_console(const YAML::Node& node, ConsoleConfig& c) {
    if (!r_.expect_map(node, "console")) return;
    r_.reject_unknown_keys(
        node, {"listen", "enabled", "allow", "token_file", "max_pending_per_address"}, "console");
    c.enabled = true;
    if (node["enabled"]) c.enabled = r_.boolean(node["enabled"], "console enabled").value_or(true);
    if (node["listen"]) parse_listen(node["listen"], "console listen", c.address, c.port);
    if (const auto allow = node["allow"]) c.allow = parse_allow(allow, "console");
    if (const auto cap = node["max_pending_per_address"])
      c.max_pending_per_address = static_cast<std::size_t>(
          r_.integer(cap, "console max_pending_per_address", 0, 1024).value_or(16));
    if (const auto file = node["token_file"]) {
      if (const auto text = expand(file, "console token_file")) {
        fs::path p(*text);
        if (p.is_relative()) p = fs::path(r_.file()).parent_path() / p;
        c.token_file = p.lexically_normal().string();
        std::string error;
        if (auto hash = read_token_hash(c.token_file, error))
          c.token_sha256 = *hash;
        else
          r_.error(file, "console token_file: " + error);
      }
    }
    if (!c.enabled || c.loopback()) return;
    // Off loopback the plant's state is visible to a network: say who may look.
    if (c.allow.empty())
      r_.error(node, fmt::format("console: listening on {} (not loopback) needs an allow list "
                                 "of the clients that may look (allow: [10.0.0.0/8], ...)",
                                 c.address));
    if (!node["token_file"])
      r_.error(node, fmt::format("console: listening on {} (not loopback) needs token_file: a "
                                 "file holding the SHA-256 of the access token "
                                 "(printf %s TOKEN | sha256sum > FILE)",
                                 c.address));
  }

  ClientAllowList parse_allow(const YAML::Node& allow, const std::string& what) {
    std::vector<Cidr> entries;
    if (!r_.expect_sequence(allow, what + " allow")) return {};
    for (const auto& item : allow) {
      auto text = r_.string(item, what + " allow");
      if (!text) continue;
      std::string error;
      if (auto c = Cidr::parse(*text, error))
        entries.push_back(*c);
      else
        r_.error(item, what + " allow: " + error);
    }
    return ClientAllowList(std::move(entries));
  }

  // `what` is "modbus" or "listener NAME"; a listener entry also has a name.
  void parse_modbus(const YAML::Node& node, ModbusConfig& m, const std::string& what,
                    bool named = false) {
    if (!r_.expect_map(node, what)) return;
    r_.reject_unknown_keys(
        node,
        {"listen", "max_clients", "when_full", "max_clients_per_address", "max_connects_per_second",
         "max_connects_per_second_per_address", "idle_timeout", "request_timeout", "word_order",
         "offline_reads", "writes_enabled", "allow", "read_only_units", "read_only_tables", "name"},
        what);
    if (!named && node["name"])
      r_.error(node["name"], what + ": the default listener has no name (it is '" +
                                 kDefaultListener + "'); further ones go under listeners:");
    if (const auto listen = node["listen"])
      parse_listen(listen, what + " listen", m.address, m.port);
    if (node["max_clients"])
      m.max_clients = static_cast<std::size_t>(
          r_.integer(node["max_clients"], what + " max_clients", 1, 1024).value_or(32));
    if (const auto wf = node["when_full"]) {
      const auto text = r_.string(wf, what + " when_full");
      if (text && (*text == "evict_idle" || *text == "refuse"))
        m.evict_when_full = *text == "evict_idle";
      else if (text)
        r_.error(wf, fmt::format("{} when_full: expected evict_idle or refuse, found '{}'", what,
                                 *text));
    }
    if (node["max_clients_per_address"])
      m.max_clients_per_address = static_cast<std::size_t>(
          r_.integer(node["max_clients_per_address"], what + " max_clients_per_address", 0, 1024)
              .value_or(0));
    for (auto [key, field] :
         {std::pair{"max_connects_per_second", &ModbusConfig::max_connects_per_second},
          std::pair{"max_connects_per_second_per_address",
                    &ModbusConfig::max_connects_per_second_per_address}})
      if (const auto rate = node[key])
        m.*field = static_cast<std::size_t>(
            r_.integer(rate, what + " " + key, 0, 100000).value_or(m.*field));
    if (node["idle_timeout"])
      m.idle_timeout =
          r_.duration(node["idle_timeout"], what + " idle_timeout").value_or(m.idle_timeout);
    if (const auto wo = node["word_order"]) {
      auto text = r_.string(wo, what + " word_order");
      if (text) {
        if (auto order = parse_word_order(*text))
          m.word_order = *order;
        else
          r_.error(wo, fmt::format("{} word_order: expected high_first or low_first, found "
                                   "'{}'",
                                   what, *text));
      }
    }
    if (const auto o = node["offline_reads"]) {
      auto text = r_.string(o, what + " offline_reads");
      if (text && *text == "exception")
        m.offline_reads = OfflineReads::exception;
      else if (text && *text == "last_value")
        m.offline_reads = OfflineReads::last_value;
      else if (text)
        r_.error(o, fmt::format("{} offline_reads: expected exception or last_value, found "
                                "'{}'",
                                what, *text));
    }
    if (node["writes_enabled"])
      m.writes_enabled =
          r_.boolean(node["writes_enabled"], what + " writes_enabled").value_or(true);
    if (node["request_timeout"])
      m.request_timeout = r_.duration(node["request_timeout"], what + " request_timeout")
                              .value_or(m.request_timeout);
    if (const auto allow = node["allow"]) m.allow = parse_allow(allow, what);
    if (const auto units = node["read_only_units"];
        units && r_.expect_sequence(units, what + " read_only_units"))
      for (const auto& item : units)
        if (auto u = r_.integer(item, what + " read_only_units", 1, 247))
          m.read_only_units.push_back(static_cast<uint8_t>(*u));
    if (const auto tables = node["read_only_tables"];
        tables && r_.expect_sequence(tables, what + " read_only_tables"))
      for (const auto& item : tables) {
        const auto t = r_.string(item, what + " read_only_tables");
        if (t && *t == "coils")
          m.read_only_coils = true;
        else if (t && *t == "holding_registers")
          m.read_only_holding = true;
        else if (t)
          r_.error(item, fmt::format("{} read_only_tables: expected coils or "
                                     "holding_registers (the only writable tables), found '{}'",
                                     what, *t));
      }
  }

  void parse_model_dirs(const YAML::Node& node, GatewayConfig& config) {
    parse_dirs(node, "models", config.model_dirs, true);
  }

  // Protocol files: a `protocols/` folder beside the configuration is read when it exists.
  void parse_protocol_dirs(const YAML::Node& node, GatewayConfig& config) {
    parse_dirs(node, "protocols", config.protocol_dirs, false);
  }

  void parse_dirs(const YAML::Node& node, std::string_view key, std::vector<std::string>& dirs,
                  bool default_required) {
    const fs::path base = fs::path(r_.file()).parent_path();
    auto add = [&](const YAML::Node& item) {
      if (auto dir = expand(item, key)) {
        fs::path p(*dir);
        const bool relative = p.is_relative();
        if (relative) p = base / p;
        std::error_code ec;
        if (!fs::is_directory(p, ec)) {
          r_.error(item, fmt::format("{}: no directory {}{}", key, p.lexically_normal().string(),
                                     relative ? fmt::format(" ('{}' is resolved from the directory "
                                                            "of this file)",
                                                            *dir)
                                              : std::string()));
          return;
        }
        dirs.push_back(p.lexically_normal().string());
      }
    };
    if (!node) {
      const fs::path fallback = (base / std::string(key)).lexically_normal();
      std::error_code ec;
      if (default_required || fs::is_directory(fallback, ec)) dirs.push_back(fallback.string());
    } else if (node.IsScalar()) {
      add(node);
    } else if (r_.expect_sequence(node, key)) {
      for (const auto& item : node) add(item);
    }
  }

  void parse_timing(const YAML::Node& node, BusTiming& t, const std::string& where, bool can) {
    if (!r_.expect_map(node, where)) return;
    r_.reject_unknown_keys(
        node,
        {"reply_timeout", "byte_timeout", "guard_time", "forward_timeout", "inter_frame_gap",
         "turnaround", "retries", "offline_after", "probe_interval", "reconnect_min",
         "reconnect_max", "heartbeat_timeout", "start_nodes", "stale_after"},
        where);
    if (node["stale_after"])
      parse_stale_after(node["stale_after"], t.stale_after, where + " stale_after");
    for (const char* key : {"heartbeat_timeout", "start_nodes"})
      if (node[key] && !can)
        r_.error(node[key], fmt::format("{} {}: only a CAN bus (can: ...) has heartbeats and NMT",
                                        where, key));
    if (node["start_nodes"])
      t.start_nodes = r_.boolean(node["start_nodes"], where + " start_nodes").value_or(false);
    auto dur = [&](const char* key, microseconds& out) {
      if (node[key]) out = r_.duration(node[key], where + " " + key).value_or(out);
    };
    dur("reply_timeout", t.link.reply_timeout);
    dur("byte_timeout", t.link.byte_timeout);
    dur("guard_time", t.link.guard_time);
    dur("forward_timeout", t.link.forward_timeout);
    t.reply_timeout_set = static_cast<bool>(node["reply_timeout"]);
    if (t.link.guard_time.count() < 0)
      r_.error(node["guard_time"], where + " guard_time: must not be negative");
    dur("inter_frame_gap", t.inter_frame_gap);
    dur("turnaround", t.turnaround);
    dur("probe_interval", t.probe_interval);
    dur("reconnect_min", t.reconnect_min);
    dur("reconnect_max", t.reconnect_max);
    dur("heartbeat_timeout", t.heartbeat_timeout);
    if (t.heartbeat_timeout.count() < 0)
      r_.error(node["heartbeat_timeout"], where + " heartbeat_timeout: must not be negative");
    if (node["retries"])
      t.retries =
          static_cast<int>(r_.integer(node["retries"], where + " retries", 0, 10).value_or(1));
    if (node["offline_after"])
      t.offline_after = static_cast<int>(
          r_.integer(node["offline_after"], where + " offline_after", 1, 100).value_or(3));
    if (t.link.reply_timeout.count() <= 0)
      r_.error(node["reply_timeout"], where + " reply_timeout: must be greater than 0");
    if (t.link.byte_timeout.count() <= 0)
      r_.error(node["byte_timeout"], where + " byte_timeout: must be greater than 0");
    if (t.reconnect_max < t.reconnect_min)
      r_.error(node, where + ": reconnect_max is smaller than reconnect_min");
  }

  void parse_stale_after(const YAML::Node& node, StaleAfter& stale, const std::string& where) {
    if (!r_.expect_map(node, where)) return;
    r_.reject_unknown_keys(node, {"failed_polls", "periods", "at_least"}, where);
    if (node["failed_polls"])
      stale.failed_polls = static_cast<uint32_t>(
          r_.integer(node["failed_polls"], where + " failed_polls", 0, 1000).value_or(3));
    if (node["periods"])
      stale.periods = static_cast<uint32_t>(
          r_.integer(node["periods"], where + " periods", 0, 1000).value_or(4));
    if (node["at_least"]) {
      stale.at_least = r_.duration(node["at_least"], where + " at_least").value_or(stale.at_least);
      if (stale.at_least.count() < 0)
        r_.error(node["at_least"], where + " at_least: must not be negative");
    }
  }

  void parse_serial(const YAML::Node& node, SerialSettings& s, const std::string& where,
                    bool device_required) {
    if (!r_.expect_map(node, where)) return;
    if (device_required)
      r_.reject_unknown_keys(
          node, {"device", "baud", "allow_nonstandard_baud", "data_bits", "parity", "stop_bits"},
          where);
    if (device_required) {
      if (auto d = r_.require(node, "device", where))
        if (auto text = expand(*d, where + " device")) s.device = *text;
    }
    if (node["baud"])
      s.baud = static_cast<unsigned>(
          r_.integer(node["baud"], where + " baud", 50, 4000000).value_or(9600));
    check_baud(node, where);
    if (node["data_bits"])
      s.data_bits = static_cast<unsigned>(
          r_.integer(node["data_bits"], where + " data_bits", 5, 8).value_or(8));
    if (node["stop_bits"])
      s.stop_bits = static_cast<unsigned>(
          r_.integer(node["stop_bits"], where + " stop_bits", 1, 2).value_or(1));
    if (const auto p = node["parity"]) {
      auto text = r_.string(p, where + " parity");
      if (text && (*text == "none" || *text == "N"))
        s.parity = 'N';
      else if (text && (*text == "even" || *text == "E"))
        s.parity = 'E';
      else if (text && (*text == "odd" || *text == "O"))
        s.parity = 'O';
      else if (text)
        r_.error(p, fmt::format("{} parity: expected none, even or odd, found '{}'", where, *text));
    }
  }

  // A typo such as 11520 or 9601 would otherwise open the port at a rate no controller uses;
  // some USB adapters do support odd rates, so they can be allowed explicitly.
  void check_baud(const YAML::Node& node, const std::string& where) {
    static constexpr int64_t standard[] = {
        50,     75,     110,     134,     150,     200,     300,     600,     1200,    1800,
        2400,   4800,   9600,    19200,   38400,   57600,   115200,  230400,  460800,  500000,
        576000, 921600, 1000000, 1152000, 1500000, 2000000, 2500000, 3000000, 3500000, 4000000};
    const auto baud_node = node["baud"];
    if (!baud_node || !baud_node.IsScalar()) return;
    const auto baud = parse_integer_text(baud_node.Scalar());
    if (!baud || std::find(std::begin(standard), std::end(standard), *baud) != std::end(standard))
      return;
    const auto allow = node["allow_nonstandard_baud"];
    if (allow && r_.boolean(allow, where + " allow_nonstandard_baud").value_or(false)) return;
    r_.error(baud_node, fmt::format("{} baud: {} is not a standard rate (such as 9600, 19200, "
                                    "38400, 57600 or 115200); if the adapter really supports "
                                    "it, add allow_nonstandard_baud: true",
                                    where, *baud));
  }

  void parse_can(const YAML::Node& node, TransportConfig& t, const std::string& where) {
    if (!r_.expect_map(node, where)) return;
    r_.reject_unknown_keys(node, {"interface"}, where);
    const auto i = r_.require(node, "interface", where);
    if (!i) return;
    const auto name = expand(*i, where + " interface");
    if (!name) return;
    // Linux interface names: 1..15 bytes (IFNAMSIZ), no '/', no white space.
    if (name->empty() || name->size() > 15 || name->find_first_of("/ \t\n:") != std::string::npos) {
      r_.error(*i, fmt::format("{} interface: '{}' is not a network interface name (such as "
                               "can0 or vcan0)",
                               where, *name));
      return;
    }
    t.can_interface = *name;
  }

  void parse_bus(const YAML::Node& node, GatewayConfig& config) {
    if (!r_.expect_map(node, "bus")) return;
    BusConfig bus;
    bus.mark = r_.mark(node);
    std::string where = "bus";
    if (auto n = r_.require(node, "name", "bus"))
      if (auto s = r_.string(*n, "bus name")) {
        bus.name = *s;
        where = "bus " + *s;
        for (const auto& other : config.buses)
          if (other.name == *s) r_.error(*n, fmt::format("{}: bus name is already used", where));
      }
    r_.reject_unknown_keys(node,
                           {"name", "protocol", "serial", "tcp", "can", "timing", "nodes",
                            "listener", "trace", "device_writes"},
                           where);
    bus_listener_ = resolve_listener(node["listener"], config, where, 0);
    if (node["trace"]) bus.trace = r_.boolean(node["trace"], where + " trace").value_or(false);
    if (auto p = r_.require(node, "protocol", where)) {
      if (auto s = r_.string(*p, where + " protocol")) {
        bus.protocol = *s;
        bus.family = make_family(*s);
        if (!bus.family)
          if (auto spec = protocols_.find(*s))
            bus.family = protocol_file::make_protocol_file_family(std::move(spec));
        if (!bus.family) {
          std::string known;
          for (const auto& f : family_names()) known += (known.empty() ? "" : ", ") + f;
          for (const auto& f : protocols_.all()) known += ", " + f->name + " (protocol file)";
          r_.error(*p, fmt::format("{}: unknown protocol '{}' (known: {})", where, *s, known));
        }
      }
    }
    const bool has_serial = static_cast<bool>(node["serial"]);
    const bool has_tcp = static_cast<bool>(node["tcp"]);
    const bool has_can = static_cast<bool>(node["can"]);
    const bool one_transport = int(has_serial) + int(has_tcp) + int(has_can) == 1;
    if (!one_transport) {
      r_.error(node, fmt::format("{}: needs exactly one of 'serial', 'tcp' or 'can'", where));
    } else if (has_can) {
      bus.transport.kind = TransportConfig::Kind::can;
      parse_can(node["can"], bus.transport, where + " can");
    } else if (has_serial) {
      bus.transport.kind = TransportConfig::Kind::serial;
      parse_serial(node["serial"], bus.transport.serial, where + " serial", true);
    } else {
      const auto tcp = node["tcp"];
      bus.transport.kind = TransportConfig::Kind::tcp;
      if (r_.expect_map(tcp, where + " tcp")) {
        r_.reject_unknown_keys(
            tcp,
            {"host", "port", "baud", "allow_nonstandard_baud", "data_bits", "parity", "stop_bits"},
            where + " tcp");
        if (auto h = r_.require(tcp, "host", where + " tcp"))
          bus.transport.host = expand(*h, where + " tcp host").value_or("");
        if (auto p = r_.require(tcp, "port", where + " tcp"))
          bus.transport.port =
              static_cast<uint16_t>(r_.integer(*p, where + " tcp port", 1, 65535).value_or(0));
        parse_serial(tcp, bus.transport.serial, where + " tcp", false);
      }
    }
    // CANopen needs a CAN interface and nothing else runs on one.
    const bool canopen = bus.protocol == "canopen";
    if (bus.family && one_transport && canopen != has_can) {
      if (canopen)
        r_.error(node["protocol"], fmt::format("{}: protocol canopen runs on a CAN interface: "
                                               "give can: {{interface: can0}} instead of {}",
                                               where, has_serial ? "serial" : "tcp"));
      else
        r_.error(node["can"], fmt::format("{}: a CAN interface carries protocol canopen, not {}",
                                          where, bus.protocol));
    }
    if (node["timing"]) parse_timing(node["timing"], bus.timing, where + " timing", has_can);
    parse_device_writes(node["device_writes"], bus, where);
    if (bus.transport.kind == TransportConfig::Kind::serial &&
        !bus.transport.serial.device.empty()) {
      std::error_code ec;
      // Not an error: a USB adapter may be plugged in later, and the bus retries opening it.
      if (!std::filesystem::exists(bus.transport.serial.device, ec))
        config.warnings.push_back(fmt::format(
            "{}: warning: {}: serial device {} does not exist (yet); the bus keeps trying to "
            "open it",
            to_string(r_.mark(node)), where, bus.transport.serial.device));
    }
    if (auto nodes = r_.require(node, "nodes", where);
        nodes && r_.expect_sequence(*nodes, where + " nodes")) {
      for (const auto& n : *nodes) parse_node(n, bus, config, where);
      if (nodes->size() == 0) r_.error(*nodes, where + ": has no nodes");
    }
    if (bus.family && r_.diagnostics().ok() && bus.transport.kind != TransportConfig::Kind::can) {
      for (const auto& n : bus.nodes) {
        const auto need = bus.family->node_timing_need(n.address, bus.timing.link);
        const auto used = node_link_timing(bus, n).reply_timeout;
        if (used < need.reply_timeout)
          config.warnings.push_back(fmt::format(
              "{}: warning: bus {} node {}: reply_timeout {} ms is below the {} ms this node "
              "needs: {}. "
              "Raise it (per node: reply_timeout in the node's entry)",
              to_string(n.mark), bus.name, n.name,
              std::chrono::duration_cast<std::chrono::milliseconds>(used).count(),
              std::chrono::duration_cast<std::chrono::milliseconds>(need.reply_timeout).count(),
              need.why));
      }
      const auto budget = compute_poll_budget(bus);
      if (budget.wire_seconds_per_second > 1.0)
        config.warnings.push_back(fmt::format(
            "{}: warning: bus {}: the configured polls need {:.0f}% of the wire time at {} baud; "
            "poll "
            "periods will stretch (raise the baud or lengthen the periods)",
            to_string(bus.mark), bus.name, budget.wire_seconds_per_second * 100,
            bus.transport.serial.baud));
    }
    const std::string link = "\n--- link " + bus.protocol + " " + bus.transport.serial.device +
                             " " + bus.transport.host + " " + bus.transport.can_interface + "\n";
    bus.signature = YAML::Dump(node) + link;
    YAML::Node without_nodes = YAML::Clone(node);
    without_nodes.remove("nodes");
    bus.link_signature = YAML::Dump(without_nodes) + link;
    // Each model's text once in the signature; a node's identity names its model by a hash of
    // that text, so that a bus of many nodes does not hold a copy of the model per node.
    std::map<const Model*, std::string> models;
    for (auto& n : bus.nodes) {
      if (!n.model) continue;
      auto [it, fresh] = models.try_emplace(n.model.get());
      if (fresh) {
        const std::string text = file_text(n.model->mark.file);
        bus.signature += "\n--- model " + n.model->name + "\n" + text;
        it->second =
            fmt::format("\n--- model {} {:016x}", n.model->name, std::hash<std::string>{}(text));
      }
      n.identity = link + "--- address " + n.address.text + it->second;
    }
    config.buses.push_back(std::move(bus));
  }

  // After the timing: some switches are settings of the timing too (nmt_start: start_nodes).
  void parse_device_writes(const YAML::Node& node, BusConfig& bus, const std::string& where) {
    // On where the settings make the family write at all.
    bus.device_writes = default_device_writes(bus.protocol);
    const auto settle = [&](const char* name, bool writes) {
      if (bus.device_writes.count(name)) bus.device_writes[name] = writes;
    };
    settle("nmt_start", bus.timing.start_nodes);
    settle("heartbeat_producer", bus.timing.heartbeat_timeout.count() > 0);
    settle("baud_switch", bus.transport.serial.baud != 0 && bus.transport.serial.baud != 9600);
    if (!node) return;
    const std::string what = where + " device_writes";
    if (!r_.expect_map(node, what)) return;
    for (const auto& entry : node) {
      const auto name = entry.first.as<std::string>();
      const auto* spec = find_device_write(bus.protocol, name);
      if (!spec) {
        std::string known;
        for (const auto& [n, on] : bus.device_writes) known += (known.empty() ? "" : ", ") + n;
        r_.error(entry.first,
                 fmt::format("{}: '{}' is no write of protocol {} (its writes: {})", what, name,
                             bus.protocol, known.empty() ? "none" : known));
        continue;
      }
      const auto on = r_.boolean(entry.second, what + " " + name);
      if (!on) continue;
      if (!*on && !spec->honoured_off && bus.device_writes[name]) {
        r_.error(entry.second,
                 fmt::format("{}: {}: false is not honoured by the {} driver of this build: it "
                             "would still write {}",
                             what, name, bus.protocol, spec->what));
        continue;
      }
      if (name == "nmt_start") {
        if (*on && !bus.timing.start_nodes) {
          r_.error(entry.second,
                   fmt::format("{}: nmt_start: true needs timing.start_nodes: true", what));
          continue;
        }
        bus.timing.start_nodes = *on;
      }
      bus.device_writes[name] = *on;
    }
  }

  static std::string file_text(const std::string& path) {
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }

  void parse_node(const YAML::Node& node, BusConfig& bus, GatewayConfig& config,
                  const std::string& bus_where) {
    if (!r_.expect_map(node, bus_where + " node")) return;
    NodeConfig n;
    n.mark = r_.mark(node);
    std::string where = bus_where + " node";
    if (auto name = r_.require(node, "name", where))
      if (auto s = r_.string(*name, where + " name")) {
        n.name = *s;
        where = fmt::format("node {}", *s);
        if (!node_names_.insert(*s).second)
          r_.error(*name, fmt::format("{}: node name is already used", where));
      }
    r_.reject_unknown_keys(node,
                           {"name", "address", "model", "unit_id", "poll", "setpoints", "limits",
                            "reply_timeout", "listener", "profile_unit", "axis_units"},
                           where);
    n.listener = resolve_listener(node["listener"], config, where, bus_listener_);
    n.stale_after = bus.timing.stale_after;
    if (node["reply_timeout"]) {
      n.reply_timeout = r_.duration(node["reply_timeout"], where + " reply_timeout");
      if (n.reply_timeout && n.reply_timeout->count() <= 0)
        r_.error(node["reply_timeout"], where + " reply_timeout: must be greater than 0");
    }
    if (auto a = r_.require(node, "address", where)) {
      if (auto text = r_.string(*a, where + " address"); text && bus.family) {
        std::string error;
        if (auto addr = bus.family->parse_address(*text, error)) {
          n.address = *addr;
          for (const auto& other : bus.nodes)
            if (other.address.text == addr->text)
              r_.error(*a, fmt::format("{}: address {} is already used by node {} on bus {}", where,
                                       addr->text, other.name, bus.name));
        } else {
          r_.error(*a, fmt::format("{} address: {}", where, error));
        }
      }
    }
    if (auto m = r_.require(node, "model", where)) {
      if (auto name = r_.string(*m, where + " model")) {
        n.model = library_.find(*name);
        if (!n.model) {
          std::string known;
          for (const auto& k : library_.names()) known += (known.empty() ? "" : ", ") + k;
          r_.error(*m, fmt::format("{}: unknown model '{}' (models found: {})", where, *name,
                                   known.empty() ? "none" : known));
        } else if (bus.family && n.model->family != bus.protocol) {
          r_.error(*m, fmt::format("{}: model {} is for family {}, but bus {} speaks {}", where,
                                   *name, n.model->family, bus.name, bus.protocol));
        } else if (bus.family && validated_.insert(n.model.get()).second) {
          bus.family->validate_model(*n.model, r_.diagnostics());
          bus.family->compile_commands(*library_.for_compiling(*name));
        }
        if (bus.family && n.model && bus.family->model_options_apply_to_bus())
          for (const auto& other : bus.nodes)
            if (other.model && other.model != n.model && other.model->options != n.model->options) {
              r_.error(*m, fmt::format("{}: model {}'s options differ from those of model {} (node "
                                       "{}), but {} options apply to the whole bus",
                                       where, n.model->name, other.model->name, other.name,
                                       bus.protocol));
              break;
            }
      }
    }
    if (auto u = r_.require(node, "unit_id", where)) {
      if (auto id = r_.integer(*u, where + " unit_id", 1, 247)) {
        n.unit_id = static_cast<uint8_t>(*id);
        const auto [it, fresh] =
            unit_ids_.try_emplace({n.listener, n.unit_id}, UnitOwner{n.name, r_.mark(*u)});
        if (!fresh)
          r_.error(*u, fmt::format("{}: unit_id {} is already used by node {} ({}) on listener {}",
                                   where, *id, it->second.node, to_string(it->second.mark),
                                   config.listener_name(n.listener)));
      }
    }
    if (const auto poll = node["poll"]; poll && r_.expect_map(poll, where + " poll")) {
      for (const auto& e : poll) {
        const std::string cls = e.first.Scalar();
        if (n.model && !n.model->find_poll_class(cls))
          r_.error(e.first,
                   fmt::format("{}: model {} has no poll class '{}'", where, n.model->name, cls));
        if (auto d = r_.duration(e.second, where + " poll " + cls)) {
          if (d->count() <= 0)
            r_.error(e.second, fmt::format("{}: poll period must be greater than 0", where));
          n.poll_periods[cls] = *d;
        }
      }
    }
    if (const auto sp = node["setpoints"]; sp && r_.expect_map(sp, where + " setpoints")) {
      for (const auto& e : sp) {
        const std::string name = e.first.Scalar();
        const SetpointDef* def = n.model ? n.model->find_setpoint(name) : nullptr;
        if (n.model && !def) {
          r_.error(e.first,
                   fmt::format("{}: model {} has no setpoint '{}'", where, n.model->name, name));
          continue;
        }
        if (!def) continue;
        const int64_t lo = def->min.value_or(min_value(def->type));
        const int64_t hi = def->max.value_or(max_value(def->type));
        if (auto v = r_.integer(e.second, where + " setpoint " + name, lo, hi))
          n.setpoints[name] = *v;
      }
    }
    if (const auto limits = node["limits"]; limits && r_.expect_map(limits, where + " limits")) {
      for (const auto& e : limits) {
        const std::string name = e.first.Scalar();
        const std::string what = where + " limits " + name;
        if (!n.model) continue;
        std::optional<ValueType> type;
        if (const auto* p = n.model->find_point(name); p && p->writable())
          type = p->type;
        else if (const auto* s = n.model->find_setpoint(name))
          type = s->type;
        if (!type) {
          r_.error(e.first, fmt::format("{}: model {} has no writable point or setpoint '{}'",
                                        where, n.model->name, name));
          continue;
        }
        if (!r_.expect_map(e.second, what)) continue;
        r_.reject_unknown_keys(e.second, {"min", "max"}, what);
        WriteLimits l;
        if (e.second["min"])
          l.min = r_.integer(e.second["min"], what + " min", min_value(*type), max_value(*type));
        if (e.second["max"])
          l.max = r_.integer(e.second["max"], what + " max", min_value(*type), max_value(*type));
        if (l.min && l.max && *l.min > *l.max)
          r_.error(e.second,
                   fmt::format("{}: min {} is greater than max {}", what, *l.min, *l.max));
        n.limits[name] = l;
      }
    }
    parse_axis_units(node, where, n, config);
    bus.nodes.push_back(std::move(n));
  }

  // profile_unit: N (a model with one profile axis) or axis_units: {x: N, y: M}.
  void parse_axis_units(const YAML::Node& node, const std::string& where, NodeConfig& n,
                        const GatewayConfig& config) {
    const auto claim = [&](const YAML::Node& at, const std::string& axis) {
      const auto id = r_.integer(at, where + " profile unit", 1, 247);
      if (!id) return;
      const auto unit = static_cast<uint8_t>(*id);
      const auto [it, fresh] =
          unit_ids_.try_emplace({n.listener, unit}, UnitOwner{n.name + "." + axis, r_.mark(at)});
      if (!fresh)
        r_.error(at, fmt::format("{}: unit_id {} is already used by {} ({}) on listener {}", where,
                                 *id, it->second.node, to_string(it->second.mark),
                                 config.listener_name(n.listener)));
      n.axis_units[axis] = unit;
    };
    if (node["profile_unit"] && node["axis_units"])
      r_.error(node, where + ": give profile_unit or axis_units, not both");
    if (const auto p = node["profile_unit"]) {
      if (n.model && n.model->profile_axes.size() != 1)
        r_.error(p, fmt::format("{}: model {} has {} profile axes; name them under axis_units",
                                where, n.model->name, n.model->profile_axes.size()));
      else if (n.model)
        claim(p, n.model->profile_axes.front().name);
    }
    if (const auto a = node["axis_units"]; a && r_.expect_map(a, where + " axis_units")) {
      for (const auto& e : a) {
        const std::string axis = e.first.Scalar();
        if (n.model && !n.model->find_profile_axis(axis)) {
          std::string known;
          for (const auto& k : n.model->profile_axes) known += (known.empty() ? "" : ", ") + k.name;
          r_.error(e.first, fmt::format("{}: model {} has no profile axis '{}' (axes: {})", where,
                                        n.model->name, axis, known.empty() ? "none" : known));
          continue;
        }
        claim(e.second, axis);
      }
    }
  }

  YamlReader& r_;
  ModelLibrary library_;
  protocol_file::ProtocolLibrary protocols_;
  std::set<std::string> node_names_;
  struct UnitOwner {
    std::string node;
    SourceMark mark;
  };
  std::map<std::pair<std::size_t, uint8_t>, UnitOwner> unit_ids_;  // by (listener, unit ID)
  std::vector<SourceMark> listener_marks_;                         // by listener index
  std::size_t bus_listener_ = 0;  // the listener of the bus being parsed
  std::set<const Model*> validated_;
};

}  // namespace

std::optional<LoadedConfig> load_gateway_config(const std::string& path, Diagnostics& diagnostics) {
  YamlReader reader(path, diagnostics);
  ConfigParser parser(reader);
  auto gateway = parser.parse(reader.load_file());
  if (!gateway || !diagnostics.ok()) return std::nullopt;
  LoadedConfig loaded;
  loaded.register_map =
      RegisterMap::build(gateway->node_bindings(0), gateway->modbus.word_order, diagnostics);
  for (std::size_t i = 1; i < gateway->listener_count(); ++i)
    loaded.listener_maps.push_back(RegisterMap::build(
        gateway->node_bindings(i), gateway->listener_modbus(i).word_order, diagnostics));
  if (!diagnostics.ok()) return std::nullopt;
  loaded.gateway = std::move(*gateway);
  return loaded;
}

}  // namespace fieldgate
