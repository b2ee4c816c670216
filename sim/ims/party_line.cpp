#include "sim/ims/party_line.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "sim/common/split.hpp"

namespace fieldgate::sim::ims {
namespace {

constexpr char kEscape = 0x1b;
constexpr char kControlC = 0x03;

bool valid_name(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= 0x5b && c <= 0x60);
}

bool no_echo_command(char c) {
  return c == 'P' || c == 'Q' || c == 'q' || c == 'X';
}

// The commands that answer with a value (§4): Z z ^ ] [ and A129.
bool is_query(std::string_view body) {
  if (body.empty()) return false;
  if (std::string_view("Zz^][").find(body.front()) != std::string_view::npos) return true;
  if (body.front() != 'A') return false;
  body.remove_prefix(1);
  while (!body.empty() && body.front() == ' ') body.remove_prefix(1);
  while (!body.empty() && body.back() == ' ') body.remove_suffix(1);
  return body == "129";
}

}  // namespace

std::vector<char> parse_names(std::string_view text) {
  std::vector<char> names;
  for (const std::string_view item : split(text, ',')) {
    if (item.size() != 1 || !valid_name(item[0]))
      throw std::invalid_argument("unit names are single characters A-Z, a-z or [\\]^_`, found '" +
                                  std::string(item) + "'");
    if (std::find(names.begin(), names.end(), item[0]) != names.end())
      throw std::invalid_argument("unit name '" + std::string(item) +
                                  "' is listed twice (use the duplicate control command)");
    names.push_back(item[0]);
  }
  return names;
}

PartyLine::PartyLine(PartyLineOptions options, FaultInjection& faults,
                     std::function<SimTime()> clock, SimTime now)
    : options_(std::move(options)),
      faults_(faults),
      clock_(std::move(clock)),
      random_(options_.seed) {
  for (const char name : options_.names)
    units_.emplace(name,
                   Unit{Indexer(name, options_.home, now, options_.result_format), true, false});
}

LineDeviceHooks PartyLine::hooks() {
  LineDeviceHooks hooks;
  hooks.frame = &PartyLine::frame;
  hooks.respond = [this](std::string_view request, SimTime now) { return respond(request, now); };
  hooks.echo = [this](std::string_view received) { return echo(received); };
  return hooks;
}

std::size_t PartyLine::frame(std::string_view pending) {
  for (std::size_t i = 0; i < pending.size(); ++i) {
    const char c = pending[i];
    if (c == kEscape || c == kControlC) return i == 0 ? 1 : i;
    if (c == '\n') return i + 1;
  }
  return 0;
}

Indexer* PartyLine::unit(char name) {
  const auto it = units_.find(name);
  return it == units_.end() ? nullptr : &it->second.indexer;
}

bool PartyLine::online(char name) const {
  const auto it = units_.find(name);
  return it != units_.end() && it->second.online;
}

std::vector<PartyLine::Unit*> PartyLine::units_named(char name) {
  std::vector<Unit*> found;
  const auto it = units_.find(name);
  if (it != units_.end() && it->second.online) found.push_back(&it->second);
  return found;
}

std::vector<PartyLine::Unit*> PartyLine::online_units() {
  std::vector<Unit*> found;
  for (auto& [name, unit] : units_)
    if (unit.online) found.push_back(&unit);
  return found;
}

char PartyLine::disturbed(char c) {
  if (c == '\n') return c;
  switch (line_.fault) {
    case Fault::garbage: {
      std::uniform_int_distribution<int> byte(0, 255);
      char g;
      do {
        g = static_cast<char>(byte(random_));
      } while (g == '\n' || g == '\r');
      return g;
    }
    case Fault::collision:
      // Two transmitters on one pair: framing errors, nothing a host can read.
      return static_cast<char>((c & 0x5f) | 0x80);
    default:
      return c;
  }
}

std::string PartyLine::collide(std::string_view bytes) {
  std::string out;
  for (const char c : bytes) out += c == '\n' ? c : static_cast<char>((c & 0x5f) | 0x80);
  return out;
}

void PartyLine::start_line(char first, std::string& out) {
  line_ = {};
  line_.started = true;
  line_.text = std::string(1, first);
  if (first == '*') {
    // v1.15+: every unit executes and, presumably, echoes (§2) — all at once.
    const std::size_t n = online_units().size();
    line_.target = Target::all;
    line_.echoing = n > 0;
    line_.fault = n > 1 ? Fault::collision : Fault::none;
    return;
  }
  if (first == '@') {
    line_.target = Target::soft_stop;
    return;
  }
  const auto named = units_named(first);
  if (named.empty()) return;  // no such name: silence (§2)
  line_.target = Target::unit;
  line_.echoing = true;
  if (faults_.garbage_replies > 0) {
    --faults_.garbage_replies;
    line_.fault = Fault::garbage;
  } else if (faults_.truncated_replies > 0) {
    --faults_.truncated_replies;
    line_.fault = Fault::truncate;
  } else if (named.front()->duplicate) {
    line_.fault = Fault::collision;
  }
  if (options_.echo_name) out += disturbed(first);
}

// A read holds what arrived since the one before it, but not when each character came: a
// simulator that was not scheduled for a while reads a paced line's characters together. They
// count as back to back when the line started in this read (one write, as an unpaced host
// sends a line; the name and the first character may come together), or when too little time
// passed since the line's previous read for them to have come a spacing apart.
bool PartyLine::back_to_back(std::size_t in_this_read, bool started_in_this_read,
                             SimTime now) const {
  if (in_this_read < 2) return false;
  if (started_in_this_read) return true;
  return now - line_.last_read < in_this_read * options_.overrun_spacing;
}

std::string PartyLine::echo(std::string_view received) {
  std::string out;
  std::size_t in_this_read = 0;
  bool started_in_this_read = false;
  const SimTime now = clock_();
  for (const char c : received) {
    if (c == kEscape || c == kControlC) {
      line_ = {};  // ESC clears the input line; ^C resets the unit
      continue;
    }
    if (!line_.started) {
      if (c != '\n') {
        start_line(c, out);
        started_in_this_read = true;
        line_.last_read = now;
      }
      continue;
    }
    line_.text += c;
    ++line_.body;
    ++in_this_read;
    if (line_.target == Target::unit || line_.target == Target::all) {
      if (line_.body == 1 && no_echo_command(c)) line_.echoing = false;
      if (line_.body == 1 && c == 'W' && line_.target == Target::unit) line_.hold_linefeed = true;
      if (line_.fault == Fault::truncate && line_.body > 1) line_.echoing = false;
    }
    if (line_.target == Target::unit && options_.overrun_above > 0 &&
        line_.fault != Fault::overrun && back_to_back(in_this_read, started_in_this_read, now)) {
      // Characters back to back while the unit steps fast: its UART overruns (p.14) and the
      // line is lost.
      const auto named = units_named(line_.text.front());
      if (!named.empty() && named.front()->indexer.step_rate(now) > options_.overrun_above) {
        line_.fault = Fault::overrun;
        line_.echoing = false;
        ++named.front()->overruns;
      }
    }
    if (c == '\n') {
      if (line_.target == Target::unit) {
        const std::string_view body = std::string_view(line_.text).substr(1, line_.body - 1);
        line_.withheld_linefeed =
            line_.echoing &&
            (is_query(body) ? options_.result_on_echo_line : options_.linefeed_at_execution);
      }
      if (line_.echoing && !line_.hold_linefeed && !line_.withheld_linefeed) out += disturbed(c);
      heard_.push_back(std::move(line_));
      line_ = {};
      continue;
    }
    if (line_.echoing) out += disturbed(c);
  }
  if (line_.started) line_.last_read = now;
  return out;
}

DeviceReply PartyLine::respond(std::string_view request, SimTime now) {
  DeviceReply reply;
  if (request.empty()) return reply;
  const char first = request.front();
  if (first == kEscape) {
    for (auto* u : online_units()) u->indexer.hard_stop(now);
    return reply;
  }
  if (first == kControlC) {
    for (auto* u : online_units()) u->indexer.reset(now);
    return reply;
  }
  if (request.back() != '\n') return reply;  // cut short by ESC or ^C: never executed

  std::optional<Line> heard;
  while (!heard_.empty()) {
    Line l = std::move(heard_.front());
    heard_.pop_front();
    if (l.text == request) {
      heard = std::move(l);
      break;
    }
  }
  if (!heard) {
    // The echo did not see it (silence was switched off mid-line): take it as heard, no fault.
    Line l;
    l.text = std::string(request);
    l.target = first == '*'                 ? Target::all
               : first == '@'               ? Target::soft_stop
               : units_named(first).empty() ? Target::none
                                            : Target::unit;
    heard = std::move(l);
  }
  const std::string_view body = request.substr(1, request.size() - 2);
  const auto bytes_of = [&](const Indexer::Outcome& o) {
    std::string bytes;
    if (o.kind == Indexer::Outcome::Kind::result) bytes = o.text;
    if (o.kind == Indexer::Outcome::Kind::completion && options_.completion) bytes = "\r\n";
    return bytes;
  };
  switch (heard->target) {
    case Target::none:
      return reply;
    case Target::soft_stop:
      for (auto* u : online_units()) u->indexer.soft_stop(now);
      return reply;
    case Target::all: {
      const auto units = online_units();
      for (auto* u : units) {
        const auto o = u->indexer.execute(body, now);
        reply.bytes = bytes_of(o);
        reply.extra_delay = std::max(reply.extra_delay, o.delay);
      }
      if (units.size() > 1) reply.bytes = collide(reply.bytes);
      return reply;
    }
    case Target::unit: {
      if (heard->fault == Fault::overrun) return reply;
      const auto units = units_named(first);
      if (units.empty()) return reply;
      const auto o = units.front()->indexer.execute(body, now);
      if (heard->fault == Fault::truncate) return reply;  // the rest of its answer is lost
      if (heard->withheld_linefeed && !heard->hold_linefeed) {
        // The echo's LF was left out: the result ends the echo's line, or the LF comes at
        // execution after the completion's CR.
        if (o.kind == Indexer::Outcome::Kind::result)
          reply.bytes = options_.result_on_echo_line ? o.text : "\n" + o.text;
        else if (o.kind == Indexer::Outcome::Kind::completion && options_.completion)
          reply.bytes = "\r\n";
        else
          reply.bytes = "\n";
      } else {
        reply.bytes = (heard->hold_linefeed ? "\n" : "") + bytes_of(o);
      }
      reply.extra_delay = o.delay;
      if (heard->fault == Fault::collision) reply.bytes = collide(reply.bytes);
      return reply;
    }
  }
  return reply;
}

std::optional<char> PartyLine::name_argument(std::span<const std::string> arguments,
                                             std::string& error) {
  if (arguments.empty() || arguments[0].size() != 1) {
    error = "error: expected a unit name";
    return std::nullopt;
  }
  const char name = arguments[0][0];
  if (units_.find(name) == units_.end()) {
    error = "error: no unit named '" + arguments[0] + "'";
    return std::nullopt;
  }
  return name;
}

std::optional<std::string> PartyLine::control(std::string_view verb,
                                              std::span<const std::string> arguments, SimTime now) {
  std::string error;
  if (verb == "axis-off" || verb == "axis-on") {
    const auto name = name_argument(arguments, error);
    if (!name || arguments.size() != 1)
      return name ? "error: usage: " + std::string(verb) + " NAME" : error;
    units_.at(*name).online = verb == "axis-on";
    return "ok " + std::string(verb) + " " + arguments[0];
  }
  if (verb == "duplicate") {
    const auto name = name_argument(arguments, error);
    if (!name) return error;
    if (arguments.size() != 2 || (arguments[1] != "on" && arguments[1] != "off"))
      return std::string("error: usage: duplicate NAME on|off");
    units_.at(*name).duplicate = arguments[1] == "on";
    return "ok duplicate " + arguments[0] + " " + arguments[1];
  }
  if (verb == "position" || verb == "inputs") {
    const auto name = name_argument(arguments, error);
    if (!name) return error;
    const auto value = arguments.size() == 2 ? parse_control_integer(arguments[1]) : std::nullopt;
    if (!value) return "error: usage: " + std::string(verb) + " NAME VALUE";
    if (verb == "position")
      units_.at(*name).indexer.set_position(now, static_cast<double>(*value));
    else
      units_.at(*name).indexer.set_inputs(static_cast<int>(*value));
    return "ok " + std::string(verb) + " " + arguments[0] + " " + arguments[1];
  }
  if (verb == "limit") {
    const auto name = name_argument(arguments, error);
    if (!name) return error;
    const std::string which = arguments.size() == 2 ? arguments[1] : "";
    if (which != "plus" && which != "minus" && which != "both" && which != "none")
      return std::string("error: usage: limit NAME plus|minus|both|none");
    units_.at(*name).indexer.set_limits(which == "plus" || which == "both",
                                        which == "minus" || which == "both");
    return "ok limit " + arguments[0] + " " + which;
  }
  if (verb == "status") {
    const auto name = name_argument(arguments, error);
    if (!name) return error;
    Unit& u = units_.at(*name);
    Indexer& x = u.indexer;
    char buffer[256];
    std::snprintf(buffer, sizeof buffer,
                  "ok %c position=%.2f status=%d rate=%.0f outputs=%d eeprom_writes=%d "
                  "slew=%.0f accel=%d decel=%d online=%d duplicate=%d overruns=%d",
                  *name, x.position(now), x.status(now), x.step_rate(now), x.outputs(),
                  x.eeprom_writes(), x.parameters().slew, x.parameters().accel,
                  x.parameters().decel, u.online ? 1 : 0, u.duplicate ? 1 : 0, u.overruns);
    return std::string(buffer);
  }
  if (verb == "reset") {
    for (auto& [name, unit] : units_) unit.indexer.reset(now);
    return std::string("ok reset");
  }
  return std::nullopt;
}

std::string PartyLine::control_help() {
  return "axis-off NAME     the unit stops listening (as if unpowered): silence\n"
         "axis-on NAME      the unit answers again\n"
         "duplicate NAME on|off  a second unit with the same name garbles every reply\n"
         "position NAME N   set the position counter (as if moved by the jog inputs)\n"
         "limit NAME plus|minus|both|none  limit switches A (+) and B (-)\n"
         "inputs NAME MASK  IN1..IN3 as bits 0..2\n"
         "status NAME       position, status, step rate, outputs, EEPROM writes\n"
         "reset             power-cycle every unit (saved parameters, position 0)\n";
}

}  // namespace fieldgate::sim::ims
