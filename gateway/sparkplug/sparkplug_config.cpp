#include "gateway/sparkplug/sparkplug_config.hpp"

#include <fmt/format.h>

#include <fstream>
#include <sstream>

namespace fieldgate::sparkplug {

std::string SparkplugConfig::effective_client_id() const {
  if (!client_id.empty()) return client_id;
  return fmt::format("fieldgate-{}-{}", group_id, edge_node_id);
}

int64_t SparkplugConfig::deadband(ValueType type) const {
  const auto it = deadbands.find(type);
  return it == deadbands.end() ? 0 : it->second;
}

namespace {

// Sparkplug IDs are topic levels: no wildcard or level separator.
bool valid_id(const std::string& id) {
  return !id.empty() && id.find_first_of("+#/") == std::string::npos;
}

void parse_broker(YamlReader& r, const YAML::Node& node, SparkplugConfig& c) {
  const auto url = r.string(node, "sparkplug broker");
  if (!url) return;
  std::string rest = *url;
  if (const auto scheme = rest.find("://"); scheme != std::string::npos) {
    const std::string s = rest.substr(0, scheme);
    if (s == "mqtt" || s == "tcp") {
      c.tls = false;
    } else if (s == "mqtts" || s == "ssl") {
      c.tls = true;
    } else {
      r.error(node, fmt::format("sparkplug broker: unknown scheme '{}' (mqtt:// or mqtts://)", s));
      return;
    }
    rest = rest.substr(scheme + 3);
  }
  c.port = c.tls ? 8883 : 1883;
  std::string host = rest;
  if (!rest.empty() && rest.front() == '[') {  // [IPv6]:port
    const auto close = rest.find(']');
    if (close == std::string::npos) {
      r.error(node, fmt::format("sparkplug broker: unclosed '[' in '{}'", *url));
      return;
    }
    host = rest.substr(1, close - 1);
    rest = rest.substr(close + 1);
    if (!rest.empty() && rest.front() != ':') {
      r.error(node, fmt::format("sparkplug broker: expected ':port' after ']' in '{}'", *url));
      return;
    }
  } else if (const auto colon = rest.rfind(':'); colon != std::string::npos) {
    host = rest.substr(0, colon);
    rest = rest.substr(colon);
  } else {
    rest.clear();
  }
  if (!rest.empty()) {
    const auto port = parse_integer_text(rest.substr(1));
    if (!port || *port < 1 || *port > 65535) {
      r.error(node, fmt::format("sparkplug broker: bad port in '{}' (1-65535)", *url));
      return;
    }
    c.port = static_cast<uint16_t>(*port);
  }
  if (host.empty()) {
    r.error(node, fmt::format("sparkplug broker: no host in '{}'", *url));
    return;
  }
  c.host = host;
}

std::string readable_file(YamlReader& r, const YAML::Node& node, std::string_view what) {
  const auto path = r.string(node, what);
  if (!path) return {};
  std::ifstream in(*path);
  if (!in) r.error(node, fmt::format("{}: cannot read '{}'", what, *path));
  return *path;
}

}  // namespace

void parse_sparkplug_config(YamlReader& r, const YAML::Node& node, SparkplugConfig& c) {
  if (!r.expect_map(node, "sparkplug")) return;
  r.reject_unknown_keys(
      node,
      {"enabled", "broker", "client_id", "group_id", "edge_node_id", "tls", "username",
       "password_file", "keepalive", "reconnect", "scan_interval", "diagnostics_interval",
       "deadbands", "commands_enabled", "primary_host_id"},
      "sparkplug");
  c.enabled =
      node["enabled"] ? r.boolean(node["enabled"], "sparkplug enabled").value_or(false) : true;
  if (node["broker"]) parse_broker(r, node["broker"], c);
  for (auto [key, field] :
       {std::pair{"group_id", &c.group_id}, {"edge_node_id", &c.edge_node_id}}) {
    const auto v = r.require(node, key, "sparkplug");
    if (!v) continue;
    if (auto text = r.string(*v, std::string("sparkplug ") + key)) {
      if (!valid_id(*text))
        r.error(*v, fmt::format("sparkplug {}: '{}' must be non-empty without '+', '#' or '/'", key,
                                *text));
      *field = *text;
    }
  }
  if (node["client_id"])
    c.client_id = r.string(node["client_id"], "sparkplug client_id").value_or("");
  if (const auto tls = node["tls"]; tls && r.expect_map(tls, "sparkplug tls")) {
    r.reject_unknown_keys(tls, {"ca_file", "cert_file", "key_file"}, "sparkplug tls");
    if (tls["ca_file"]) c.ca_file = readable_file(r, tls["ca_file"], "sparkplug tls ca_file");
    if (tls["cert_file"])
      c.cert_file = readable_file(r, tls["cert_file"], "sparkplug tls cert_file");
    if (tls["key_file"]) c.key_file = readable_file(r, tls["key_file"], "sparkplug tls key_file");
    if (c.cert_file.empty() != c.key_file.empty())
      r.error(tls, "sparkplug tls: cert_file and key_file go together");
    if (!c.ca_file.empty()) c.tls = true;
  }
  if (node["username"]) c.username = r.string(node["username"], "sparkplug username").value_or("");
  if (node["password_file"]) {
    c.password_file = readable_file(r, node["password_file"], "sparkplug password_file");
    std::ifstream in(c.password_file);
    std::stringstream text;
    text << in.rdbuf();
    c.password = text.str();
    while (!c.password.empty() && (c.password.back() == '\n' || c.password.back() == '\r'))
      c.password.pop_back();
    if (c.username.empty())
      r.error(node["password_file"], "sparkplug password_file: needs a username");
  }
  const auto positive = [&](const char* key, std::chrono::microseconds& out) {
    if (!node[key]) return;
    const std::string what = std::string("sparkplug ") + key;
    if (auto d = r.duration(node[key], what)) {
      if (d->count() <= 0)
        r.error(node[key], fmt::format("{}: must be greater than 0", what));
      else
        out = *d;
    }
  };
  positive("keepalive", c.keepalive);
  if (node["keepalive"] && c.keepalive < std::chrono::seconds(5))
    r.error(node["keepalive"], "sparkplug keepalive: at least 5s (libmosquitto refuses less)");
  positive("scan_interval", c.scan_interval);
  positive("diagnostics_interval", c.diagnostics_interval);
  if (const auto rc = node["reconnect"]; rc && r.expect_map(rc, "sparkplug reconnect")) {
    r.reject_unknown_keys(rc, {"min", "max"}, "sparkplug reconnect");
    if (rc["min"])
      c.reconnect_min = r.duration(rc["min"], "sparkplug reconnect min").value_or(c.reconnect_min);
    if (rc["max"])
      c.reconnect_max = r.duration(rc["max"], "sparkplug reconnect max").value_or(c.reconnect_max);
    if (c.reconnect_min.count() <= 0 || c.reconnect_min > c.reconnect_max)
      r.error(rc, "sparkplug reconnect: need 0 < min <= max");
  }
  if (const auto db = node["deadbands"]; db && r.expect_map(db, "sparkplug deadbands")) {
    for (const auto& e : db) {
      const std::string name = e.first.Scalar();
      const auto type = parse_value_type(name);
      if (!type) {
        r.error(e.first,
                fmt::format("sparkplug deadbands: unknown point type '{}' (boolean, int16, uint16, "
                            "int32, uint32)",
                            name));
        continue;
      }
      if (auto v = r.integer(e.second, "sparkplug deadbands " + name, 0, 0xffffffffLL))
        c.deadbands[*type] = *v;
    }
  }
  if (node["commands_enabled"])
    c.commands_enabled =
        r.boolean(node["commands_enabled"], "sparkplug commands_enabled").value_or(false);
  if (node["primary_host_id"]) {
    if (auto id = r.string(node["primary_host_id"], "sparkplug primary_host_id")) {
      if (!valid_id(*id))
        r.error(node["primary_host_id"],
                fmt::format("sparkplug primary_host_id: '{}' must be non-empty without '+', '#' "
                            "or '/'",
                            *id));
      c.primary_host_id = *id;
    }
  }
}

}  // namespace fieldgate::sparkplug
