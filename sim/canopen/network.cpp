#include "network.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <sstream>
#include <stdexcept>

namespace fieldgate::sim::canopen {

namespace {

std::optional<unsigned long> parse_number(std::string_view text) {
  int base = 10;
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    text.remove_prefix(2);
  }
  unsigned long value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value, base);
  if (ec != std::errc{} || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

std::uint8_t node_id(std::string_view text) {
  const auto v = parse_number(text);
  if (!v || *v < 1 || *v > 127)
    throw std::invalid_argument(fmt::format("'{}' is not a node ID (1..127)", text));
  return static_cast<std::uint8_t>(*v);
}

std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

}  // namespace

std::vector<std::uint8_t> parse_node_ids(std::string_view text) {
  std::vector<std::uint8_t> ids;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t comma = std::min(text.find(',', pos), text.size());
    const std::string_view item = text.substr(pos, comma - pos);
    if (const auto dash = item.find('-'); dash != std::string_view::npos) {
      const std::uint8_t first = node_id(item.substr(0, dash));
      const std::uint8_t last = node_id(item.substr(dash + 1));
      if (last < first) throw std::invalid_argument(fmt::format("empty range '{}'", item));
      for (int id = first; id <= last; ++id) ids.push_back(static_cast<std::uint8_t>(id));
    } else {
      ids.push_back(node_id(item));
    }
    pos = comma + 1;
  }
  std::sort(ids.begin(), ids.end());
  if (std::adjacent_find(ids.begin(), ids.end()) != ids.end())
    throw std::invalid_argument(fmt::format("node ID given twice in '{}'", text));
  return ids;
}

Network::Network(NodeConfig config, FrameSink sink, LogSink log)
    : config_(std::move(config)), sink_(std::move(sink)), log_(std::move(log)) {}

Node& Network::add_node(std::uint8_t id, TimePoint now) {
  auto& slot = nodes_[id];
  if (!slot) slot = std::make_unique<Node>(id, config_, sink_, log_);
  slot->power_on(now);
  return *slot;
}

Node* Network::node(std::uint8_t id) {
  const auto it = nodes_.find(id);
  return it == nodes_.end() ? nullptr : it->second.get();
}

std::vector<std::uint8_t> Network::ids() const {
  std::vector<std::uint8_t> out;
  for (const auto& [id, n] : nodes_) out.push_back(id);
  return out;
}

void Network::receive(const CanFrame& frame, TimePoint now) {
  for (auto& [id, n] : nodes_) n->receive(frame, now);
}

void Network::advance(TimePoint now) {
  for (auto& [id, n] : nodes_) n->advance(now);
}

TimePoint Network::next_deadline() const {
  TimePoint t = TimePoint::max();
  for (const auto& [id, n] : nodes_) t = std::min(t, n->next_deadline());
  return t;
}

Network::CommandResult Network::execute(std::string_view line, TimePoint now) {
  const auto w = words(line);
  if (w.empty() || w[0].front() == '#') return {true, false, ""};
  const std::string_view cmd = w[0];
  try {
    if (cmd == "quit" || cmd == "exit") return {true, true, "bye"};
    if (cmd == "help")
      return {true, false,
              "commands: power-off ID | power-on ID | fault ID CODE | status [ID] | quit"};
    if (cmd == "status") {
      std::ostringstream out;
      for (const auto& [id, n] : nodes_) {
        if (w.size() > 1 && id != node_id(w[1])) continue;
        if (out.tellp() > 0) out << "\n";
        out << fmt::format("node {} {} nmt={} 402={} sw=0x{:04X} pos={} vel={} err=0x{:02X} hb={}",
                           id, n->powered() ? "on" : "off", to_string(n->nmt_state()),
                           to_string(n->drive().state()), n->drive().statusword(),
                           n->drive().position_actual(), n->drive().velocity_actual(),
                           n->error_register(), n->heartbeat_ms());
      }
      return {true, false, out.str()};
    }
    if (cmd == "power-off" || cmd == "power-on" || cmd == "fault") {
      const std::size_t args = cmd == "fault" ? 3 : 2;
      if (w.size() != args)
        return {false, false, fmt::format("usage: {} ID{}", cmd, cmd == "fault" ? " CODE" : "")};
      const std::uint8_t id = node_id(w[1]);
      Node* n = node(id);
      if (!n) return {false, false, fmt::format("no node {}", id)};
      if (cmd == "power-off") {
        n->power_off();
      } else if (cmd == "power-on") {
        n->power_on(now);
      } else {
        const auto code = parse_number(w[2]);
        if (!code || *code == 0 || *code > 0xFFFF)
          return {false, false, fmt::format("'{}' is not an error code (1..0xFFFF)", w[2])};
        if (!n->powered()) return {false, false, fmt::format("node {} is powered off", id)};
        n->inject_fault(static_cast<std::uint16_t>(*code), now);
      }
      return {true, false, fmt::format("{} {}", cmd, id)};
    }
  } catch (const std::invalid_argument& e) {
    return {false, false, e.what()};
  }
  return {false, false, fmt::format("unknown command '{}' (try help)", cmd)};
}

}  // namespace fieldgate::sim::canopen
