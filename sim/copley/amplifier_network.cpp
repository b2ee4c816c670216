#include "sim/copley/amplifier_network.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <variant>

#include "sim/common/control_channel.hpp"
#include "sim/common/split.hpp"

namespace fieldgate::sim::copley {
namespace {

// Longer lines are answered with e 1 ("Too much data passed with command"). The manual gives
// no buffer size; no legitimate command comes near this.
constexpr std::size_t kMaxLineLength = 256;
constexpr std::uint32_t kPowerUpBaud = 9600;

int parse_int(std::string_view text, int low, int high, const char* what) {
  const auto value = parse_control_integer(text);
  if (!value || *value < low || *value > high) {
    throw std::invalid_argument(std::string("bad ") + what + " '" + std::string(text) + "'");
  }
  return static_cast<int>(*value);
}

}  // namespace

std::vector<int> parse_node_list(std::string_view text) {
  std::vector<int> nodes{0};
  for (const std::string_view part : split(text, ',')) {
    nodes.push_back(parse_int(part, 0, 127, "node ID"));
  }
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

void parse_axes(std::string_view text, NetworkOptions& options) {
  for (const std::string_view part : split(text, ',')) {
    const std::size_t colon = part.find(':');
    if (colon == std::string_view::npos) {
      options.default_axes = parse_int(part, 1, 3, "axis count");
    } else {
      options.axes[parse_int(part.substr(0, colon), 0, 127, "node ID")] =
          parse_int(part.substr(colon + 1), 1, 3, "axis count");
    }
  }
}

AmplifierNetwork::AmplifierNetwork(NetworkOptions options, SimTime now)
    : options_(std::move(options)) {
  if (std::find(options_.nodes.begin(), options_.nodes.end(), 0) == options_.nodes.end()) {
    options_.nodes.push_back(0);
  }
  for (const int id : options_.nodes) {
    if (id < 0 || id > 127) throw std::invalid_argument("node IDs are 0-127");
    const auto it = options_.axes.find(id);
    const int count = it != options_.axes.end() ? it->second : options_.default_axes;
    if (count < 1 || count > 3) throw std::invalid_argument("amplifiers have 1-3 axes");
    Node& node = nodes_[id];
    for (int k = 0; k < count; ++k) node.axes.emplace_back(options_.stepper, now);
  }
  if (options_.baud != kPowerUpBaud) {
    // Started "already raised": as if the host had sent s r0x90 <baud> after power-up.
    const std::int64_t baud = options_.baud;
    for (AmplifierAxis& a : nodes_.at(0).axes) {
      if (a.set(Bank::ram, var::baud_rate, std::span(&baud, 1), now)) {
        throw std::invalid_argument("baud must be 9600-115200");
      }
    }
  }
}

std::size_t AmplifierNetwork::frame(std::string_view pending) {
  const std::size_t cr = pending.find('\r');
  return cr == std::string_view::npos ? 0 : cr + 1;
}

AmplifierNetwork::Node* AmplifierNetwork::find(int id) {
  const auto it = nodes_.find(id);
  return it == nodes_.end() ? nullptr : &it->second;
}

AmplifierAxis* AmplifierNetwork::axis(int node, char letter) {
  Node* n = find(node);
  const auto index = static_cast<std::size_t>(letter - 'a');
  return n != nullptr && index < n->axes.size() ? &n->axes[index] : nullptr;
}

std::int32_t AmplifierNetwork::cvm_register(int node, int index) const {
  return nodes_.at(node).cvm.at(static_cast<std::size_t>(index));
}

void AmplifierNetwork::reset(Node& node, SimTime now) {
  for (AmplifierAxis& a : node.axes) a.power_up(now);
  node.cvm = {};
  node.deaf_until = now + options_.boot_time;
}

DeviceReply AmplifierNetwork::handle(std::string_view request, SimTime now) {
  std::string_view line = request;
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  const bool compact = options_.compact_replies;
  DeviceReply reply;

  Node& gateway = nodes_.at(0);
  // The gateway amplifier off or booting: nothing answers at all.
  if (!gateway.online || now < gateway.deaf_until) return reply;
  if (line.size() > kMaxLineLength) {
    reply.bytes = error_reply(Error::line_too_long, compact);
    return reply;
  }
  const AddressParse parsed = parse_address(line);
  if (parsed.error) {
    reply.bytes = error_reply(*parsed.error, compact);
    return reply;
  }
  // "0 …" addresses the gateway itself unless --zero-prefix says otherwise; only other IDs go
  // over CAN.
  const int id = parsed.address.node.value_or(0);
  if (parsed.address.node && id == 0 &&
      options_.zero_prefix != NetworkOptions::ZeroPrefix::gateway) {
    if (options_.zero_prefix == NetworkOptions::ZeroPrefix::invalid_node) {
      reply.bytes = error_reply(Error::bad_node, compact);
    } else {
      reply.bytes = error_reply(Error::can_failure, compact);
      reply.extra_delay = options_.forward_latency + options_.can_timeout;
    }
    return reply;
  }
  const bool forwarded = id != 0;
  if (forwarded) reply.extra_delay = options_.forward_latency;
  Node* node = find(id);
  if (forwarded && (node == nullptr || !node->online || now < node->deaf_until)) {
    reply.bytes = error_reply(Error::can_failure, compact);
    reply.extra_delay += options_.can_timeout;
    return reply;
  }
  // Multi-axis amplifiers want the axis letter (--missing-axis: axis a, e 33 or silence). An
  // axis the amplifier does not have is a parse error.
  if (!parsed.address.axis && node->axes.size() > 1) {
    if (options_.missing_axis == NetworkOptions::MissingAxis::parse_error) {
      reply.bytes = error_reply(Error::parse_error, compact);
      return reply;
    }
    if (options_.missing_axis == NetworkOptions::MissingAxis::silent) return reply;
  }
  const auto index = static_cast<std::size_t>(parsed.address.axis.value_or('a') - 'a');
  if (index >= node->axes.size()) {
    reply.bytes = error_reply(Error::parse_error, compact);
    return reply;
  }
  const CommandParse command = parse_command(parsed.body);
  if (command.error) {
    reply.bytes = error_reply(*command.error, compact);
    return reply;
  }
  if (command.command.code == Code::reset) {
    reset(*node, now);
    if (forwarded) {
      // §2.5: the node resets before it answers the gateway.
      reply.bytes = error_reply(Error::can_failure, compact);
    } else {
      reply.new_baud = kPowerUpBaud;
    }
    return reply;
  }
  reply.bytes = execute(*node, node->axes[index], command.command, now, reply.new_baud, !forwarded);
  return reply;
}

std::string AmplifierNetwork::execute(Node& node, AmplifierAxis& axis, const Command& command,
                                      SimTime now, std::optional<std::uint32_t>& new_baud,
                                      bool gateway) {
  const bool compact = options_.compact_replies;
  std::optional<Error> error;
  switch (command.code) {
    case Code::get: {
      auto result = axis.get(command.bank, command.variable, now);
      if (const auto* values = std::get_if<Values>(&result)) return values_reply(*values, compact);
      return error_reply(std::get<Error>(result), compact);
    }
    case Code::set:
      error = axis.set(command.bank, command.variable, command.values, now);
      if (!error && gateway && command.bank == Bank::ram && command.variable == var::baud_rate) {
        // §4.1: the ok already comes back at the new rate.
        new_baud = static_cast<std::uint32_t>(command.values[0]);
      }
      break;
    case Code::copy:
      error = axis.copy(command.bank, command.variable, now);
      break;
    case Code::trajectory:
      error = axis.trajectory(static_cast<int>(command.values[0]), now);
      break;
    case Code::cvm_register: {
      auto& reg = node.cvm.at(static_cast<std::size_t>(command.cvm_register));
      if (command.values.empty()) return register_reply(reg, compact);
      const std::int64_t v = command.values[0];
      if (v < std::numeric_limits<std::int32_t>::min() ||
          v > std::numeric_limits<std::uint32_t>::max()) {
        return error_reply(Error::out_of_range, compact);
      }
      reg = static_cast<std::int32_t>(static_cast<std::uint32_t>(v));
      break;
    }
    case Code::reset:
      break;
  }
  return error ? error_reply(*error, compact) : ok_reply();
}

std::optional<std::string> AmplifierNetwork::control(std::string_view verb,
                                                     std::span<const std::string> arguments,
                                                     SimTime now,
                                                     std::optional<std::uint32_t>& link_baud) {
  const bool node_verb = verb == "node-off" || verb == "node-on" || verb == "reset";
  const bool axis_verb = verb == "fault" || verb == "inputs";
  const bool query_verb = verb == "position";
  if (!node_verb && !axis_verb && !query_verb) return std::nullopt;
  const std::string usage = "error: usage: " + std::string(verb) +
                            (node_verb    ? " NODE"
                             : query_verb ? " NODE[.AXIS]"
                                          : " NODE[.AXIS] BITS");
  if (arguments.size() != (axis_verb ? 2u : 1u)) return usage;

  const std::string_view target = arguments[0];
  const std::size_t dot = target.find('.');
  const auto id = parse_control_integer(target.substr(0, dot));
  Node* node = id && *id >= 0 && *id <= 127 ? find(static_cast<int>(*id)) : nullptr;
  if (node == nullptr) return "error: no node " + std::string(target.substr(0, dot));
  const std::string name(target);

  if (verb == "node-off" || verb == "node-on") {
    node->online = verb == "node-on";
    return "ok " + std::string(verb) + " " + name;
  }
  if (verb == "reset") {
    reset(*node, now);
    if (*id == 0) link_baud = kPowerUpBaud;
    return "ok reset " + name;
  }
  char letter = 'a';
  if (dot != std::string_view::npos) {
    if (target.size() != dot + 2) return usage;
    letter = target[dot + 1];
  }
  AmplifierAxis* a = axis(static_cast<int>(*id), letter);
  if (a == nullptr) return "error: no axis " + name;
  if (query_verb) {
    // The event status's in-motion bit (27), as the amplifier reports it on the wire.
    const bool moving = (a->event_status(now) >> 27) & 1u;
    return "ok position " + name + " " + std::to_string(a->motor_position(now)) +
           " moving=" + (moving ? "1" : "0");
  }
  const auto bits = parse_control_integer(arguments[1]);
  if (!bits || *bits < 0 || *bits > std::numeric_limits<std::uint32_t>::max()) return usage;
  if (verb == "fault") {
    a->latch_faults(static_cast<std::uint32_t>(*bits), now);
  } else {
    a->set_inputs(static_cast<std::uint32_t>(*bits));
  }
  return "ok " + std::string(verb) + " " + name + " " + arguments[1];
}

std::string AmplifierNetwork::control_help() {
  return "node-off N       node N stops answering (e 32 via the gateway; node 0: total silence)\n"
         "node-on N        node N answers again\n"
         "reset N          power-cycle node N (node 0 also drops the link to 9600 baud)\n"
         "position N[.x]   motor position (0x32) and in-motion bit: ok position N P moving=0|1\n"
         "fault N[.x] BITS latch fault register (0xa4) bits, e.g. fault 3 512\n"
         "inputs N[.x] MASK set the digital inputs (0xa6)\n";
}

}  // namespace fieldgate::sim::copley
