#include "drivers/techno_c/techno_codec.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <iterator>
#include <utility>

#include "drivers/printable_bytes.hpp"

namespace fieldgate::techno {

namespace {

bool is_hex(char c) {
  return std::isxdigit(static_cast<unsigned char>(c)) != 0;
}

std::string_view trim_spaces(std::string_view s) {
  while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
  while (!s.empty() && s.back() == ' ') s.remove_suffix(1);
  return s;
}

// Strips the CR/LF a controller may put after a reply; a lone CR is itself a handshake.
std::string_view strip_terminator(std::string_view frame) {
  while (frame.size() > 1 && (frame.back() == '\r' || frame.back() == '\n')) frame.remove_suffix(1);
  return frame;
}

ParsedReply malformed(std::string problem) {
  ParsedReply r;
  r.kind = ParsedReply::Kind::malformed;
  r.problem = std::move(problem);
  return r;
}

ParsedReply error_reply(char code) {
  ParsedReply r;
  r.kind = ParsedReply::Kind::error;
  r.code = code;
  return r;
}

// A one-character frame of a query: an error handshake, or something that is no reply.
ParsedReply single_character(char c, std::string_view what) {
  if (is_error_code(c)) return error_reply(c);
  if (c == kAck) return malformed(fmt::format("acknowledge without {}", what));
  return malformed(
      fmt::format("unexpected character '{}'", printable_bytes(std::string_view(&c, 1))));
}

// Command letters (p.29 ff.) and what they are.
constexpr std::pair<char, CommandKind> kCommandLetters[] = {
    {'A', CommandKind::move_relative},
    {'a', CommandKind::move_relative},
    {'M', CommandKind::move_absolute},
    {'m', CommandKind::move_absolute},
    {'R', CommandKind::home},
    {'r', CommandKind::home},
    {'S', CommandKind::start_program},
    {'s', CommandKind::start_program},
    {'Y', CommandKind::circle},
    {'n', CommandKind::zero},
    {'d', CommandKind::home_speed},
    {'P', CommandKind::position},
    {'b', CommandKind::peek},
    {'c', CommandKind::peek},
    {'B', CommandKind::poke},
    {'e', CommandKind::plane},
    {'z', CommandKind::interpolation_3d},
    {'f', CommandKind::circle_direction},
    {'k', CommandKind::clear_program},
    {'i', CommandKind::enter_program},
    {'u', CommandKind::save_to_card},
    {'t', CommandKind::trace},
};

}  // namespace

Command classify(std::string_view command) {
  Command c;
  if (command == kStopCommand) {
    c.kind = CommandKind::stop;
    return c;
  }
  if (command == kResetCommand) {
    c.kind = CommandKind::reset;
    return c;
  }
  if (command.empty()) return c;
  if (std::all_of(command.begin(), command.end(),
                  [](char ch) { return std::isdigit(static_cast<unsigned char>(ch)) != 0; })) {
    c.kind = CommandKind::specify_axes;
    c.values = command;
    return c;
  }
  c.letter = command.front();
  c.values = command.substr(1);
  const auto* entry =
      std::find_if(std::begin(kCommandLetters), std::end(kCommandLetters),
                   [&](const std::pair<char, CommandKind>& e) { return e.first == c.letter; });
  if (entry == std::end(kCommandLetters)) return c;
  c.kind = entry->second;
  if (c.kind == CommandKind::circle) {
    // The manual does not say when Y answers; like the capital moves, at the end [inf].
    c.handshake = Handshake::at_end;
    return c;
  }
  if (c.kind == CommandKind::move_relative || c.kind == CommandKind::move_absolute ||
      c.kind == CommandKind::home || c.kind == CommandKind::start_program)
    c.handshake = std::isupper(static_cast<unsigned char>(c.letter)) ? Handshake::at_end
                                                                     : Handshake::at_start;
  return c;
}

bool is_motion(CommandKind kind) {
  return kind == CommandKind::move_relative || kind == CommandKind::move_absolute ||
         kind == CommandKind::home || kind == CommandKind::circle ||
         kind == CommandKind::start_program;
}

std::string encode_command(int device, std::string_view command, int stop_count) {
  if (command == kStopCommand) return std::string(static_cast<std::size_t>(stop_count), kStopByte);
  if (command == kResetCommand) return std::string(1, kResetByte);
  std::string out = "@";
  out += static_cast<char>('0' + device);
  out += command;
  out += '\r';
  return out;
}

std::optional<std::vector<int64_t>> parse_values(std::string_view text) {
  std::vector<int64_t> values;
  if (trim_spaces(text).empty()) return values;
  while (true) {
    const auto comma = text.find(',');
    std::string_view token = trim_spaces(text.substr(0, comma));
    if (!token.empty() && token.front() == '+') token.remove_prefix(1);
    if (token.empty()) return std::nullopt;
    int64_t v = 0;
    const auto [p, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    if (ec != std::errc{} || p != token.data() + token.size()) return std::nullopt;
    values.push_back(v);
    if (comma == std::string_view::npos) return values;
    text.remove_prefix(comma + 1);
  }
}

bool valid_axes_definition(int axes) {
  return axes == 1 || axes == 3 || axes == 5 || axes == 7;
}

int axis_count(int axes) {
  return std::popcount(static_cast<unsigned>(axes & 7));
}

int move_value_count(int axes) {
  switch (axes) {
    case 1:
      return 2;
    case 3:
      return 4;
    case 5:
      return 6;
    case 7:
      return 8;
    default:
      return 0;
  }
}

bool valid_axis_mask(int64_t mask, int axes) {
  return mask >= 1 && mask <= 7 && (mask & ~static_cast<int64_t>(axes)) == 0;
}

bool is_error_code(char c) {
  switch (c) {
    case '2':
    case '3':
    case '4':
    case '5':
    case '6':
    case '7':
    case '8':
    case 'B':
    case 'c':
    case 'D':
    case 'G':
    case 'z':
    case '\r':
      return true;
    default:
      return false;
  }
}

std::string_view error_text(char c) {
  switch (c) {
    case '0':
      return "no error";
    case '2':
      return "emergency stop or limit switch encountered (moves: home switch on, target outside "
             "the reach of an axis)";
    case '3':
      return "illegal number of axes (an axis mask names an axis that is not defined)";
    case '4':
      return "axis not defined (the axes definition has not been sent since power-up)";
    case '5':
      return "syntax error (or an illegal step count or sign)";
    case '6':
      return "out of memory";
    case '7':
      return "illegal parameters (or a value count that does not fit the defined axes)";
    case '8':
    case 'B':
      return "illegal branch";
    case 'c':
      return "loop error";
    case 'D':
      return "illegal speed (valid 30..10000 steps/s)";
    case 'G':
      return "no data for execution in memory (no program stored)";
    case 'z':
      return "internal \"SW\" error";
    case '\r':
      return "unexpected end of command";
    default:
      return "not a handshake character of the manual";
  }
}

std::string describe_error(char c) {
  const std::string shown =
      c == '\r' ? std::string("CR") : printable_bytes(std::string_view(&c, 1));
  return fmt::format("'{}' ({}): {}", shown, static_cast<int>(static_cast<unsigned char>(c)),
                     error_text(c));
}

std::size_t handshake_frame(std::string_view buf) {
  return buf.empty() ? 0 : 1;
}

std::size_t position_frame(std::string_view buf, PositionReply mode) {
  if (buf.empty()) return 0;
  const char first = buf.front();
  // Error characters that cannot start hex data end the reply at once; '2'..'8' and 'D' are hex
  // digits too, so those are told apart by the idle gap (or by the ack mode).
  if (first == 'G' || first == 'z') return 1;
  if (const auto end = buf.find_first_of("\r\n"); end != std::string_view::npos) return end + 1;
  switch (mode) {
    case PositionReply::ack:
      if (first != kAck) return 1;
      return buf.size() >= kPositionDigits + 1 ? kPositionDigits + 1 : 0;
    case PositionReply::bare:
      return buf.size() >= kPositionDigits ? kPositionDigits : 0;
    case PositionReply::automatic:
      return buf.size() >= kPositionDigits + 1 ? kPositionDigits + 1 : 0;
  }
  return 0;
}

std::size_t peek_frame(std::string_view buf) {
  if (buf.empty()) return 0;
  if (buf.front() != kAck) return 1;
  if (const auto end = buf.find_first_of("\r\n"); end != std::string_view::npos) return end + 1;
  return buf.size() >= 3 ? 3 : 0;
}

int64_t sign_extend_24(uint32_t raw) {
  raw &= 0xffffffu;
  return (raw & 0x800000u) ? static_cast<int64_t>(raw) - 0x1000000 : static_cast<int64_t>(raw);
}

ParsedReply parse_handshake(std::string_view frame) {
  if (frame.size() != 1)
    return malformed(
        fmt::format("expected one handshake character, got '{}'", printable_bytes(frame)));
  if (frame.front() == kAck) {
    ParsedReply r;
    r.kind = ParsedReply::Kind::ok;
    r.code = kAck;
    return r;
  }
  if (is_error_code(frame.front())) return error_reply(frame.front());
  return malformed(fmt::format("unexpected character '{}'", printable_bytes(frame)));
}

ParsedReply parse_positions(std::string_view frame, int fitted_axes) {
  frame = strip_terminator(frame);
  if (frame.empty()) return malformed("empty position reply");
  if (frame.size() == 1) return single_character(frame.front(), "position data");
  if (frame.size() % 6 == 1 && frame.front() == kAck) frame.remove_prefix(1);
  // 18 digits, or 6 per axis of a controller with fewer (the manual gives no length for those).
  const std::size_t fitted_digits = static_cast<std::size_t>(std::clamp(fitted_axes, 1, 3)) * 6;
  if (frame.size() != kPositionDigits && frame.size() != fitted_digits)
    return malformed(
        fitted_digits == kPositionDigits
            ? fmt::format("expected 18 hex digits (X Y Z), got '{}'", printable_bytes(frame))
            : fmt::format("expected 18 or {} hex digits, got '{}'", fitted_digits,
                          printable_bytes(frame)));
  ParsedReply r;
  r.kind = ParsedReply::Kind::ok;
  r.code = kAck;
  for (std::size_t i = 0; i < frame.size(); i += 6) {
    const std::string_view field = frame.substr(i, 6);
    uint32_t raw = 0;
    if (!std::all_of(field.begin(), field.end(), is_hex))
      return malformed(fmt::format("'{}' is not hex", printable_bytes(field)));
    std::from_chars(field.data(), field.data() + field.size(), raw, 16);
    r.values.push_back(sign_extend_24(raw));
  }
  while (r.values.size() < 3) r.values.push_back(0);
  return r;
}

ParsedReply parse_peek(std::string_view frame) {
  frame = strip_terminator(frame);
  if (frame.empty()) return malformed("empty peek reply");
  if (frame.size() == 1) return single_character(frame.front(), "data");
  if (frame.size() != 3 || frame.front() != kAck || !is_hex(frame[1]) || !is_hex(frame[2]))
    return malformed(
        fmt::format("expected '0' and two hex digits, got '{}'", printable_bytes(frame)));
  ParsedReply r;
  r.kind = ParsedReply::Kind::ok;
  r.code = kAck;
  uint32_t v = 0;
  std::from_chars(frame.data() + 1, frame.data() + 3, v, 16);
  r.values.push_back(v);
  return r;
}

double leg_seconds(double distance, double speed, double acceleration) {
  distance = std::abs(distance);
  if (distance <= 0) return 0;
  speed = std::max(speed, 1.0);
  acceleration = std::max(acceleration, 1.0);
  if (distance >= speed * speed / acceleration) return distance / speed + speed / acceleration;
  return 2 * std::sqrt(distance / acceleration);
}

std::vector<int> pair_axes(int axes, int plane) {
  switch (axes) {
    case 1:
      return {0};
    case 3:
      return {0, 1};
    case 5:
      return {0, 2, 2};
    case 7:
      if (plane == 1) return {0, 2, 1, 1};  // XZ plane: the e1 pair order is not shown [inf]
      if (plane == 2) return {1, 2, 0, 0};  // YZ plane (manual p.58 example)
      return {0, 1, 2, 2};
    default:
      return {};
  }
}

std::optional<MotionEstimate> estimate_motion(const Command& command,
                                              const std::vector<int64_t>& values,
                                              const MotionContext& context) {
  MotionEstimate estimate;
  estimate.end_position = context.position;
  auto& position = estimate.end_position;
  const double a = context.acceleration;
  switch (command.kind) {
    case CommandKind::move_relative:
    case CommandKind::move_absolute: {
      const auto axes_of_pair = pair_axes(context.axes, context.plane);
      if (axes_of_pair.empty() || values.size() != axes_of_pair.size() * 2) return std::nullopt;
      // Legs in sequence: the plane pair together, then each further pair (digest §1.4).
      std::vector<double> legs;
      for (std::size_t i = 0; i < axes_of_pair.size(); ++i) {
        const int axis = axes_of_pair[i];
        const auto u = static_cast<std::size_t>(axis);
        const int64_t g = values[2 * i];
        const double speed = static_cast<double>(values[2 * i + 1]);
        double distance = 0;
        if (command.kind == CommandKind::move_relative) {
          distance = static_cast<double>(std::llabs(g));
          if (position[u]) *position[u] += g;
        } else {
          distance = position[u] ? static_cast<double>(std::llabs(g - *position[u]))
                                 : static_cast<double>(std::llabs(g)) + context.travel[u];
          position[u] = g;
        }
        const double t = leg_seconds(distance, speed, a);
        const bool joins_plane_leg = i == 1 && context.axes != 5;
        if (joins_plane_leg)
          legs.back() = std::max(legs.back(), t);
        else
          legs.push_back(t);
      }
      for (const double t : legs) estimate.seconds += t;
      return estimate;
    }
    case CommandKind::home: {
      if (values.size() != 1) return std::nullopt;
      const int64_t mask = values[0];
      // A combined home runs Z, then Y, then X (p.41).
      for (int axis = 2; axis >= 0; --axis) {
        if (!(mask & (int64_t{1} << axis))) continue;
        const auto u = static_cast<std::size_t>(axis);
        estimate.seconds += leg_seconds(context.travel[u], context.home_speed[u], a);
        position[u] = 0;
      }
      return estimate.seconds > 0 ? std::optional(estimate) : std::nullopt;
    }
    case CommandKind::circle:
      if (values.size() != 7) return std::nullopt;
      estimate.seconds =
          leg_seconds(static_cast<double>(values[0]), static_cast<double>(values[1]), a);
      position[0].reset();
      position[1].reset();
      return estimate;
    default:
      return std::nullopt;
  }
}

std::optional<int> parse_device(std::string_view text, std::string& error) {
  if (text.size() != 1 || !std::isdigit(static_cast<unsigned char>(text.front()))) {
    error = fmt::format(
        "Techno device number must be one digit 0-9 (the manual's standard is 0; '@07' is device "
        "0 with axes 7), found '{}'",
        text);
    return std::nullopt;
  }
  return text.front() - '0';
}

}  // namespace fieldgate::techno
