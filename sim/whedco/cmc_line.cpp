#include "sim/whedco/cmc_line.hpp"

#include <stdexcept>

#include "sim/common/control_channel.hpp"
#include "sim/common/split.hpp"

namespace fieldgate::sim::whedco {
namespace {

int address_of(std::string_view text) {
  if (text.size() != 1 || text[0] < '0' || text[0] > '7')
    throw std::invalid_argument("bad CMC-0 address '" + std::string(text) + "' (0-7)");
  return text[0] - '0';
}

// "WXYZ" applies to every unit, "4:XY,5:WXYZ" per unit.
std::map<int, std::string> per_unit(std::string_view text, std::string& all) {
  std::map<int, std::string> out;
  if (text.empty()) return out;
  for (const auto part : split(text, ',')) {
    const auto colon = part.find(':');
    if (colon == std::string_view::npos)
      all = std::string(part);
    else
      out[address_of(part.substr(0, colon))] = std::string(part.substr(colon + 1));
  }
  return out;
}

std::optional<int> address_argument(std::string_view text) {
  if (text.size() != 1 || text[0] < '0' || text[0] > '7') return std::nullopt;
  return text[0] - '0';
}

// The axis letter (either case), or 0.
char axis_argument(std::span<const std::string> arguments, std::size_t i) {
  if (i >= arguments.size() || arguments[i].size() != 1) return 0;
  const char c = arguments[i][0];
  const char letter = static_cast<char>(c >= 'a' && c <= 'z' ? c - 'a' + 'A' : c);
  return kAxisOrder.find(letter) == std::string_view::npos ? 0 : letter;
}

}  // namespace

std::vector<UnitOptions> parse_units(std::string_view addresses, std::string_view axes,
                                     std::string_view non_echo, std::string_view steppers) {
  std::string all_axes = "WXYZ";
  const auto axes_of = per_unit(axes, all_axes);
  std::string all_steppers;
  const auto steppers_of = per_unit(steppers, all_steppers);
  std::vector<UnitOptions> units;
  for (const auto part : split(addresses, ',')) {
    UnitOptions u;
    u.address = address_of(part);
    for (const auto& other : units)
      if (other.address == u.address) throw std::invalid_argument("address listed twice");
    const auto a = axes_of.find(u.address);
    u.axes = a != axes_of.end() ? a->second : all_axes;
    const auto s = steppers_of.find(u.address);
    u.steppers = s != steppers_of.end() ? s->second : all_steppers;
    units.push_back(u);
  }
  if (non_echo == "all") {
    for (auto& u : units) u.echo = false;
  } else if (!non_echo.empty()) {
    for (const auto part : split(non_echo, ',')) {
      const int address = address_of(part);
      bool found = false;
      for (auto& u : units)
        if (u.address == address) {
          u.echo = false;
          found = true;
        }
      if (!found) throw std::invalid_argument("--non-echo names a unit that is not on the line");
    }
  }
  return units;
}

CmcLine::CmcLine(LineOptions options, SimTime now) : options_(std::move(options)) {
  for (const auto& u : options_.units) units_.emplace(u.address, CmcUnit(u, now));
}

CmcUnit* CmcLine::unit(int address) {
  const auto it = units_.find(address);
  return it == units_.end() ? nullptr : &it->second;
}

std::size_t CmcLine::frame(std::string_view pending) {
  const auto cr = pending.find('\r');
  return cr == std::string_view::npos ? 0 : cr + 1;
}

std::string CmcLine::echo(std::string_view received) {
  std::string out;
  for (const char c : received) {
    if (line_start_) {
      if (c == '\r' || c == '\n') continue;
      line_start_ = false;
      CmcUnit* u = (c >= '0' && c <= '7') ? unit(c - '0') : nullptr;
      echoing_ = u && u->online() && u->echo();
    }
    if (echoing_ && !(c == '\r' && options_.style == ReplyStyle::inline_echo)) {
      out += c;
      if (c == '\r') out += '\n';
    }
    if (c == '\r') line_start_ = true;
  }
  return out;
}

DeviceReply CmcLine::handle(std::string_view request, SimTime now) {
  DeviceReply reply;
  while (!request.empty() && (request.back() == '\r' || request.back() == '\n'))
    request.remove_suffix(1);
  while (!request.empty() && (request.front() == '\n' || request.front() == '\r'))
    request.remove_prefix(1);
  if (request.empty() || request[0] < '0' || request[0] > '7') return reply;
  CmcUnit* u = unit(request[0] - '0');
  if (!u || !u->online()) return reply;
  const std::string_view body = request.substr(1);
  const std::string text = u->execute(body, now);
  if (options_.style == ReplyStyle::terminal) {
    reply.bytes = "\r\n";
    if (!text.empty()) reply.bytes += (text[0] == '-' ? "" : " ") + text + "\r\n";
  } else if (options_.style == ReplyStyle::inline_echo && u->echo()) {
    reply.bytes = text.empty() ? "\r\n" : " " + text + "\r\n";
  } else if (!text.empty()) {
    reply.bytes = text + "\r\n";
  }
  reply.bytes += '*';
  if (body.starts_with("RP") || body.starts_with("RC") || body.starts_with("FE"))
    reply.extra_delay = options_.position_read_delay;
  return reply;
}

std::optional<std::string> CmcLine::control(std::string_view verb,
                                            std::span<const std::string> arguments, SimTime now) {
  const auto target = [&]() -> CmcUnit* {
    if (arguments.empty()) return nullptr;
    const auto a = address_argument(arguments[0]);
    return a ? unit(*a) : nullptr;
  };
  const auto integer = [&](std::size_t i) -> std::optional<long long> {
    return i < arguments.size() ? parse_control_integer(arguments[i]) : std::nullopt;
  };
  if (verb == "unit-off" || verb == "unit-on") {
    CmcUnit* u = target();
    if (!u || arguments.size() != 1) return "error: usage: " + std::string(verb) + " ADDR";
    u->set_online(verb == "unit-on");
    return "ok " + std::string(verb) + " " + arguments[0];
  }
  if (verb == "echo") {
    CmcUnit* u = target();
    if (!u || arguments.size() != 2 || (arguments[1] != "on" && arguments[1] != "off"))
      return std::string("error: usage: echo ADDR on|off");
    u->set_echo(arguments[1] == "on");
    return "ok echo " + arguments[0] + " " + arguments[1];
  }
  if (verb == "fault") {
    CmcUnit* u = target();
    const char axis = axis_argument(arguments, 1);
    std::optional<long long> code;
    if (arguments.size() == 3 && arguments[2].size() == 1 &&
        (arguments[2][0] == 'A' || arguments[2][0] == 'a'))
      code = 10;
    else
      code = integer(2);
    if (!u || !axis || !code || arguments.size() != 3 ||
        !u->inject_fault(axis, static_cast<int>(*code), now))
      return std::string(
          "error: usage: fault ADDR AXIS CODE (axis present on the unit; code 0, 2-9 or A, "
          "8 clears)");
    return "ok fault " + arguments[0] + " " + std::string(1, axis) + " " + arguments[2];
  }
  if (verb == "power-cycle") {
    CmcUnit* u = target();
    if (!u || arguments.size() != 1) return std::string("error: usage: power-cycle ADDR");
    u->power_cycle(now);
    return "ok power-cycle " + arguments[0];
  }
  if (verb == "inputs") {
    CmcUnit* u = target();
    const auto mask = integer(1);
    if (!u || !mask || *mask < 0 || *mask > 0xfff || arguments.size() != 2)
      return std::string("error: usage: inputs ADDR MASK (bit n-1 = I/O n, 12 bits)");
    u->set_inputs(static_cast<int>(*mask));
    return "ok inputs " + arguments[0] + " " + arguments[1];
  }
  if (verb == "analog") {
    CmcUnit* u = target();
    const auto channel = integer(1);
    const auto counts = integer(2);
    if (!u || !channel || !counts || arguments.size() != 3 ||
        !u->set_analog(static_cast<int>(*channel), static_cast<int>(*counts)))
      return std::string("error: usage: analog ADDR CHANNEL COUNTS (channel 1-4)");
    return "ok analog " + arguments[0] + " " + arguments[1] + " " + arguments[2];
  }
  if (verb == "home") {
    CmcUnit* u = target();
    const char axis = axis_argument(arguments, 1);
    const auto position = integer(2);
    if (!u || !axis || !position || arguments.size() != 3 ||
        !u->set_home(axis, static_cast<double>(*position)))
      return std::string("error: usage: home ADDR AXIS POSITION (pulses, machine coordinates)");
    return "ok home " + arguments[0] + " " + std::string(1, axis) + " " + arguments[2];
  }
  if (verb == "profile") {
    CmcUnit* u = target();
    const auto number = integer(1);
    if (!u || !number || arguments.size() != 3)
      return std::string("error: usage: profile ADDR N LINE;LINE;... (without address)");
    std::vector<std::string> lines;
    for (const auto l : split(arguments[2], ';'))
      if (!l.empty()) lines.emplace_back(l);
    std::string error;
    if (!u->define_profile(static_cast<int>(*number), lines, error)) return "error: " + error;
    return "ok profile " + arguments[0] + " " + arguments[1] + " " + std::to_string(lines.size()) +
           " lines";
  }
  if (verb == "position") {
    CmcUnit* u = target();
    const char axis = axis_argument(arguments, 1);
    if (!u || !axis || arguments.size() != 2 || !u->has_axis(axis))
      return std::string("error: usage: position ADDR AXIS");
    const double p = *u->commanded_position(axis, now);
    return "ok position " + arguments[0] + " " + std::string(1, axis) + " " + format_user_value(p);
  }
  return std::nullopt;
}

std::string CmcLine::control_help() {
  return "unit-off ADDR     the CMC-0 at ADDR stops answering (unit-on ADDR: back)\n"
         "echo ADDR on|off  switch SW2-5 (communication format) of a unit\n"
         "fault ADDR AXIS CODE  fault an axis (code 0, 2-7, 9, A; 8 = Unit Functional)\n"
         "power-cycle ADDR  power failure: axes stop at 0, faults read Power Failure\n"
         "inputs ADDR MASK  levels of the user I/O used as inputs (bit n-1 = I/O n)\n"
         "analog ADDR CH COUNTS  analog input 1-4 in A/D counts (-2047..2047)\n"
         "home ADDR AXIS POS  where the home input and index are (pulses, machine)\n"
         "profile ADDR N L1;L2;...  store profile N (lines without address)\n"
         "position ADDR AXIS  report the commanded position in pulses\n";
}

}  // namespace fieldgate::sim::whedco
