#include "sim/centent/daisy_chain.hpp"

#include <charconv>
#include <stdexcept>

#include "sim/common/split.hpp"

namespace fieldgate::sim::centent {

namespace {

std::optional<int> digit(char c) {
  if (c < '0' || c > '9') return std::nullopt;
  return c - '0';
}

std::string strip(std::string_view s) {
  std::string out;
  for (char c : s)
    if (c != ' ' && c != '\t') out += c;
  return out;
}

}  // namespace

std::vector<int> parse_unit_list(std::string_view text) {
  std::vector<int> units;
  for (const std::string_view item : split(text, ',')) {
    const auto d = item.size() == 1 ? digit(item[0]) : std::nullopt;
    if (!d)
      throw std::invalid_argument("unit numbers are digits 0-9, found '" + std::string(item) + "'");
    units.push_back(*d);
  }
  return units;
}

DaisyChain::DaisyChain(ChainOptions options, SimTime now) : options_(std::move(options)) {
  for (int number : options_.units) {
    Node node;
    node.unit = std::make_unique<Cn0170Unit>(number, options_.unit, now);
    node.baud = options_.power_up ? Baud::waiting : Baud::locked;
    // Which unit is selected after power-up is not documented; a lone unit works without .Un
    // (p.48 Getting Started), so each unit starts out selecting itself.
    node.selected = options_.select_self_after_reset ? number : -1;
    nodes_.push_back(std::move(node));
  }
}

std::size_t DaisyChain::frame(std::string_view pending) {
  const auto end = pending.find_first_of("\r\n");
  return end == std::string_view::npos ? 0 : end + 1;
}

std::string DaisyChain::message(const Node& node, std::string_view text, bool unit_message) const {
  std::string out;
  const int number = node.unit->number();
  if (number != 0 && (!unit_message || options_.prefix_unit_messages)) {
    out += static_cast<char>('0' + number);
    out += options_.prefix_separator;
  }
  out += text;
  out += options_.terminator;
  return out;
}

Cn0170Unit* DaisyChain::find(int number) {
  for (auto& n : nodes_)
    if (n.unit->number() == number) return n.unit.get();
  return nullptr;
}

void DaisyChain::advance(SimTime now) {
  for (auto& node : nodes_) {
    if (!node.powered || node.baud != Baud::locked) continue;
    std::vector<std::string> events;
    node.unit->advance(now, events);
    for (const auto& e : events) outbox_ += message(node, e, false);
  }
}

void DaisyChain::reset(Node& node, SimTime now) {
  node.powered = true;
  node.baud = Baud::waiting;
  node.selected = -1;
  node.unit->power_up(now);
}

DaisyChain::Pass DaisyChain::unit_command(Node& node, std::string& content, std::string& replies) {
  const std::string c = strip(content);
  Cn0170Unit& unit = *node.unit;
  // .U? : every unit answers in chain order and passes it on.
  if (c == ".U?" || c == ".u?") {
    replies += message(node, "[U" + std::to_string(unit.number()) + "]", true);
    return Pass::on;
  }
  if (c.size() >= 3 && (c[1] == 'U' || c[1] == 'u')) {
    const std::string_view rest = std::string_view(c).substr(2);
    // .Un : select n.
    if (rest.size() == 1 && digit(rest[0])) {
      node.selected = *digit(rest[0]);
      return Pass::on;
    }
    // .U=n : the first unit takes n.
    if (rest.size() == 2 && rest[0] == '=' && digit(rest[1])) {
      unit.set_number(*digit(rest[1]));
      return Pass::stop;
    }
    // .U+m=n : decrement m and pass on; at 0 take n.
    if (rest.size() == 4 && rest[0] == '+' && digit(rest[1]) && rest[2] == '=' && digit(rest[3])) {
      const int m = *digit(rest[1]);
      if (m == 0) {
        unit.set_number(*digit(rest[3]));
        return Pass::stop;
      }
      content = ".U+" + std::to_string(m - 1) + "=" + rest[3];
      return Pass::on;
    }
    // .Um=n : the unit numbered m (the nearest, if duplicated) becomes n.
    if (rest.size() == 3 && digit(rest[0]) && rest[1] == '=' && digit(rest[2])) {
      if (unit.number() != *digit(rest[0])) return Pass::on;
      unit.set_number(*digit(rest[2]));
      return Pass::stop;
    }
  }
  replies += message(node, "\"" + content + "\" ?", false);
  return Pass::stop;
}

void DaisyChain::trap(std::size_t position, const std::string& content, SimTime now,
                      std::string& replies) {
  Node& node = nodes_[position];
  ++node.lines;
  bool kill = false;
  std::vector<std::string> lines;
  for (const auto& instruction : split(content, ';')) {
    if (strip(instruction).empty()) continue;
    kill = node.unit->execute(instruction, now, lines) || kill;
  }
  for (const auto& l : lines) replies += message(node, l, false);
  if (!kill) return;
  // K is the one instruction a unit relays down the chain (p.13).
  for (std::size_t j = position + 1; j < nodes_.size(); ++j) {
    Node& next = nodes_[j];
    if (!next.powered || next.baud != Baud::locked) break;
    next.unit->kill(now);
  }
}

DeviceReply DaisyChain::handle(std::string_view line, SimTime now) {
  advance(now);
  const bool cr = !line.empty() && line.back() == '\r';
  std::string content(line);
  while (!content.empty() && (content.back() == '\r' || content.back() == '\n')) content.pop_back();
  ++stats_.lines;
  {
    const std::string c = strip(content);
    if (c.size() == 3 && c[0] == '.' && (c[1] == 'U' || c[1] == 'u') && digit(c[2])) {
      ++stats_.selections;
      ++stats_.selections_of[static_cast<std::size_t>(*digit(c[2]))];
    }
  }
  std::string replies;
  std::size_t deepest = 0;
  bool delivered = false;
  for (std::size_t i = 0; i < nodes_.size() && !delivered; ++i) {
    Node& node = nodes_[i];
    if (!node.powered || node.baud == Baud::failed) {
      if (!content.empty()) ++stats_.lost;
      delivered = true;
      break;
    }
    if (node.baud == Baud::waiting) {
      // The first character after a reset must be a CR: the unit measures the baud rate on it,
      // answers U<n> and passes the CR on (each unit of a chain answers in turn, p.1).
      const bool lone_cr = content.empty() && cr;
      if (lone_cr || (!options_.strict_autobaud && cr)) {
        node.baud = Baud::locked;
        node.selected = options_.select_self_after_reset ? node.unit->number() : -1;
        replies += message(node, "U" + std::to_string(node.unit->number()), true);
        deepest = i;
        if (lone_cr) continue;
      } else if (options_.strict_autobaud && !(content.empty() && !cr)) {
        node.baud = Baud::failed;
      }
      if (!content.empty()) ++stats_.lost;
      delivered = true;
      break;
    }
    if (content.empty()) continue;
    deepest = i;
    if (content.front() == '.') {
      if (unit_command(node, content, replies) == Pass::stop) delivered = true;
      continue;
    }
    if (node.selected == node.unit->number()) {
      trap(i, content, now, replies);
      delivered = true;
      continue;
    }
    if (options_.kill_acts_upstream)
      for (const auto& instruction : split(content, ';'))
        if (strip(instruction) == "K" || strip(instruction) == "k") node.unit->kill(now);
  }
  if (!delivered && !content.empty()) ++stats_.passed_through;
  advance(now);
  if (drop_last_lines_ > 0) {
    // A line lost on the wire: the last reply of a request that has more than one.
    const std::string& t = options_.terminator;
    const auto before_last = replies.size() >= 2 * t.size()
                                 ? replies.rfind(t, replies.size() - t.size() - 1)
                                 : std::string::npos;
    if (before_last != std::string::npos) {
      replies.resize(before_last + t.size());
      --drop_last_lines_;
    }
  }
  DeviceReply reply;
  reply.bytes = outbox_ + replies;
  outbox_.clear();
  reply.extra_delay = options_.hop_delay * static_cast<long>(2 * deepest);
  return reply;
}

DaisyChain::Node* DaisyChain::resolve(std::string_view address) {
  if (address.size() >= 2 && address[0] == '#') {
    std::size_t p = 0;
    const auto [end, ec] = std::from_chars(address.data() + 1, address.data() + address.size(), p);
    if (ec != std::errc{} || end != address.data() + address.size() || p < 1 || p > nodes_.size())
      return nullptr;
    return &nodes_[p - 1];
  }
  if (address.size() != 1 || !digit(address[0])) return nullptr;
  for (auto& n : nodes_)
    if (n.unit->number() == *digit(address[0])) return &n;
  return nullptr;
}

std::string DaisyChain::control_help() {
  return "reset N          power-cycle unit N (or #P, the P-th on the chain): it waits for its\n"
         "                 auto-baud CR and then answers U<N>\n"
         "unit-off N       remove unit N's power (it neither answers nor passes data on)\n"
         "unit-on N        restore its power (as reset)\n"
         "emit N TEXT      unit N sends TEXT unsolicited (e.g. emit 2 Q*)\n"
         "input N 1|2 0|1  set digital input IN1/IN2 of unit N\n"
         "analog N X|Y|1|2 V  set an analog input (0-255)\n"
         "aux N V          set the aux port input bits of unit N\n"
         "number #P N      give the P-th unit on the chain number N (duplicates allowed)\n"
         "position N       positions, motion and mode of unit N\n"
         "stats [N]        line, selection and instruction counters (chain, or unit N)\n"
         "drop-last-line N the next N replies of two or more lines lose their last line\n"
         "chain            unit numbers in chain order, with their state\n";
}

std::optional<std::string> DaisyChain::control(std::string_view verb,
                                               std::span<const std::string> args, SimTime now) {
  const auto need = [&](std::size_t n, const char* usage) -> std::optional<std::string> {
    if (args.size() != n) return std::string("error: usage: ") + usage;
    return std::nullopt;
  };
  const auto node_of = [&](const std::string& a) -> Node* { return resolve(a); };
  advance(now);
  if (verb == "reset" || verb == "unit-on" || verb == "unit-off") {
    if (auto e = need(1, (std::string(verb) + " N|#P").c_str())) return e;
    Node* n = node_of(args[0]);
    if (!n) return "error: no unit " + args[0];
    if (verb == "unit-off") {
      n->unit->kill(now);
      n->powered = false;
    } else {
      reset(*n, now);
    }
    return "ok " + std::string(verb) + " " + args[0];
  }
  if (verb == "emit") {
    if (args.size() < 2) return "error: usage: emit N TEXT";
    Node* n = node_of(args[0]);
    if (!n) return "error: no unit " + args[0];
    std::string text;
    for (std::size_t i = 1; i < args.size(); ++i) text += (i > 1 ? " " : "") + args[i];
    outbox_ += message(*n, text, false);
    return "ok emit " + args[0];
  }
  if (verb == "input") {
    if (auto e = need(3, "input N 1|2 0|1")) return e;
    Node* n = node_of(args[0]);
    if (!n || (args[1] != "1" && args[1] != "2") || (args[2] != "0" && args[2] != "1"))
      return "error: usage: input N 1|2 0|1";
    n->unit->set_input(args[1][0] - '0', args[2] == "1");
    return "ok input";
  }
  if (verb == "analog") {
    if (auto e = need(3, "analog N X|Y|1|2 V")) return e;
    Node* n = node_of(args[0]);
    const auto v = parse_control_integer(args[2]);
    if (!n || args[1].size() != 1 ||
        std::string_view("XY12").find(args[1][0]) == std::string::npos || !v || *v < 0 || *v > 255)
      return "error: usage: analog N X|Y|1|2 V (0-255)";
    n->unit->set_analog(args[1][0], static_cast<int>(*v), now);
    return "ok analog";
  }
  if (verb == "aux") {
    if (auto e = need(2, "aux N V")) return e;
    Node* n = node_of(args[0]);
    const auto v = parse_control_integer(args[1]);
    if (!n || !v || *v < 0 || *v > 255) return "error: usage: aux N V (0-255)";
    n->unit->set_aux_inputs(static_cast<int>(*v));
    return "ok aux";
  }
  if (verb == "number") {
    if (auto e = need(2, "number #P N")) return e;
    Node* n = node_of(args[0]);
    const auto d = args[1].size() == 1 ? digit(args[1][0]) : std::nullopt;
    if (!n || !d) return "error: usage: number #P N";
    n->unit->set_number(*d);
    return "ok number " + args[0] + " " + args[1];
  }
  if (verb == "drop-last-line") {
    if (auto e = need(1, "drop-last-line N")) return e;
    const auto v = parse_control_integer(args[0]);
    if (!v || *v < 0) return "error: usage: drop-last-line N";
    drop_last_lines_ = static_cast<int>(*v);
    return "ok drop-last-line " + args[0];
  }
  if (verb == "position") {
    if (auto e = need(1, "position N|#P")) return e;
    Node* n = node_of(args[0]);
    if (!n) return "error: no unit " + args[0];
    const Cn0170Unit& u = *n->unit;
    return "ok position unit=" + std::to_string(u.number()) +
           " x=" + std::to_string(u.position_register('X', now)) +
           " y=" + std::to_string(u.position_register('Y', now)) +
           " x_moving=" + (u.moving('X', now) ? "1" : "0") +
           " y_moving=" + (u.moving('Y', now) ? "1" : "0") + " mode=" + std::to_string(u.mode()) +
           " out1=" + (u.output(3) ? "1" : "0") + " out2=" + (u.output(4) ? "1" : "0");
  }
  if (verb == "stats") {
    if (args.empty()) {
      std::string by_unit;
      for (std::size_t i = 0; i < stats_.selections_of.size(); ++i)
        by_unit += (i ? "," : "") + std::to_string(stats_.selections_of[i]);
      return "ok stats selections=" + std::to_string(stats_.selections) +
             " lines=" + std::to_string(stats_.lines) +
             " passed=" + std::to_string(stats_.passed_through) +
             " lost=" + std::to_string(stats_.lost) + " selections_by_unit=" + by_unit;
    }
    if (auto e = need(1, "stats [N|#P]")) return e;
    Node* n = node_of(args[0]);
    if (!n) return "error: no unit " + args[0];
    const auto& c = n->unit->counters();
    const int number = n->unit->number();
    return "ok stats unit=" + std::to_string(number) + " lines=" + std::to_string(n->lines) +
           " selections=" + std::to_string(stats_.selections_of[static_cast<std::size_t>(number)]) +
           " instructions=" + std::to_string(c.instructions) +
           " queries=" + std::to_string(c.queries) + " rejects=" + std::to_string(c.rejects) +
           " kills=" + std::to_string(c.kills) + " lost=" + std::to_string(c.lost);
  }
  if (verb == "chain") {
    std::string out;
    for (const auto& n : nodes_) {
      out += (out.empty() ? "" : ",") + std::to_string(n.unit->number());
      if (!n.powered)
        out += "(off)";
      else if (n.baud == Baud::waiting)
        out += "(waiting)";
      else if (n.baud == Baud::failed)
        out += "(failed)";
    }
    return "ok chain " + out;
  }
  return std::nullopt;
}

}  // namespace fieldgate::sim::centent
