#include "gateway/sparkplug/fleet_view.hpp"

#include <fmt/format.h>

#include <vector>

#include "gateway/sparkplug/payload.hpp"

namespace fieldgate::sparkplug {

namespace {

std::vector<std::string_view> levels(std::string_view topic) {
  std::vector<std::string_view> out;
  while (true) {
    const auto slash = topic.find('/');
    out.push_back(topic.substr(0, slash));
    if (slash == std::string_view::npos) break;
    topic.remove_prefix(slash + 1);
  }
  return out;
}

// Specification 6.4.16.
std::string datatype_name(uint32_t type) {
  static const char* const names[] = {"Unknown", "Int8",    "Int16",  "Int32",    "Int64",
                                      "UInt8",   "UInt16",  "UInt32", "UInt64",   "Float",
                                      "Double",  "Boolean", "String", "DateTime", "Text"};
  return type < std::size(names) ? names[type] : fmt::format("type {}", type);
}

std::string value_text(const Metric& m) {
  if (m.is_null()) return "null";
  switch (m.datatype()) {
    case 1:
      return std::to_string(static_cast<int8_t>(m.int_value()));
    case 2:
      return std::to_string(static_cast<int16_t>(m.int_value()));
    case 3:
      return std::to_string(static_cast<int32_t>(m.int_value()));
    case 4:
      return std::to_string(static_cast<int64_t>(m.long_value()));
    case 5:
    case 6:
    case 7:
      return std::to_string(m.int_value());
    case 8:
    case 13:
      return std::to_string(m.long_value());
    case 9:
      return fmt::format("{}", m.float_value());
    case 10:
      return fmt::format("{}", m.double_value());
    case 11:
      return m.boolean_value() ? "true" : "false";
    case 12:
    case 14:
      return m.string_value();
    default:
      return "(not shown)";
  }
}

// Names the metrics of a message, recording the aliases of a birth; returns the text lines.
std::string apply_metrics(const Payload& p, std::map<std::string, FleetView::MetricState>& metrics,
                          std::map<uint64_t, std::string>& aliases, bool birth) {
  std::string out;
  for (const auto& m : p.metrics()) {
    std::string name = m.has_name() ? m.name() : std::string();
    if (birth && m.has_alias() && !name.empty()) aliases[m.alias()] = name;
    if (name.empty() && m.has_alias()) {
      const auto it = aliases.find(m.alias());
      name = it != aliases.end() ? it->second : fmt::format("alias {}", m.alias());
    }
    FleetView::MetricState& s = metrics[name];
    s.value = value_text(m);
    if (m.has_datatype()) s.datatype = datatype_name(m.datatype());
    s.timestamp_ms = m.timestamp();
    out += fmt::format("  {} = {}{}\n", name, s.value,
                       s.datatype.empty() ? "" : " (" + s.datatype + ")");
  }
  return out;
}

std::optional<uint64_t> bd_seq_of(const Payload& p) {
  for (const auto& m : p.metrics())
    if (m.name() == "bdSeq") return m.long_value();
  return std::nullopt;
}

}  // namespace

std::string FleetView::take(std::string_view topic, std::string_view payload, uint64_t now_ms) {
  const auto l = levels(topic);
  if (l.size() == 3 && l[0] == "spBv1.0" && l[1] == "STATE") {
    hosts_[std::string(l[2])] = std::string(payload);
    return fmt::format("STATE host {}: {}\n", l[2], payload);
  }
  if (l.size() < 4 || l.size() > 5 || l[0] != "spBv1.0") {
    ++malformed_;
    return fmt::format("not a Sparkplug B topic: {}\n", topic);
  }
  const std::string_view type = l[2];
  const std::string edge(l[3]);
  const std::string device = l.size() == 5 ? std::string(l[4]) : std::string();
  const auto p = decode(payload);
  if (!p) {
    ++malformed_;
    return fmt::format("{} {}{}{}: payload is not a Sparkplug B protobuf ({} bytes)\n", type, edge,
                       device.empty() ? "" : "/", device, payload.size());
  }
  std::string head = fmt::format("{} {}{}{}", type, edge, device.empty() ? "" : "/", device);
  if (p->has_seq()) head += fmt::format(" seq {}", p->seq());
  if (type == "NCMD" || type == "DCMD") {
    // A host's command: shown, not applied to the view.
    std::map<std::string, MetricState> shown;
    auto& node = nodes_[edge];
    auto& aliases = device.empty() ? node.aliases : node.devices[device].aliases;
    return head + "\n" + apply_metrics(*p, shown, aliases, false);
  }
  EdgeNode& node = nodes_[edge];
  ++node.messages;
  if (type != "NDEATH" && p->has_seq()) {
    if (node.seq && type != "NBIRTH" && p->seq() != (*node.seq + 1) % 256) {
      ++node.seq_gaps;
      head += fmt::format(" (expected seq {})", (*node.seq + 1) % 256);
    }
    node.seq = p->seq();
  }
  if (type == "NBIRTH") {
    node.born = true;
    node.changed_ms = now_ms;
    node.bd_seq = bd_seq_of(*p);
    node.metrics.clear();
    node.aliases.clear();
    for (auto& [name, d] : node.devices) d.born = false;  // each comes back with its DBIRTH
    return head + "\n" + apply_metrics(*p, node.metrics, node.aliases, true);
  }
  if (type == "NDEATH") {
    const auto bd = bd_seq_of(*p);
    if (node.bd_seq && bd && *bd != *node.bd_seq)
      return head + fmt::format(
                        " bdSeq {}: of an older session (this one began with bdSeq {}), "
                        "ignored\n",
                        *bd, *node.bd_seq);
    node.born = false;
    node.changed_ms = now_ms;
    for (auto& [name, d] : node.devices)
      if (d.born) {
        d.born = false;
        d.changed_ms = now_ms;
      }
    return head + (bd ? fmt::format(" bdSeq {}", *bd) : "") +
           ": the edge node and its devices are dead\n";
  }
  if (type == "NDATA") return head + "\n" + apply_metrics(*p, node.metrics, node.aliases, false);
  if (device.empty()) {
    ++malformed_;
    return head + ": a device message without a device\n";
  }
  Device& d = node.devices[device];
  ++d.messages;
  if (type == "DBIRTH") {
    d.born = true;
    d.changed_ms = now_ms;
    d.metrics.clear();
    d.aliases.clear();
    return head + "\n" + apply_metrics(*p, d.metrics, d.aliases, true);
  }
  if (type == "DDEATH") {
    d.born = false;
    d.changed_ms = now_ms;
    return head + ": the device is dead\n";
  }
  if (type == "DDATA") return head + "\n" + apply_metrics(*p, d.metrics, d.aliases, false);
  ++malformed_;
  return head + ": unknown message type\n";
}

}  // namespace fieldgate::sparkplug
