// Every serial family's frame splitter and reply interpreter on arbitrary bytes: the first
// input byte picks the family (and its mode), the rest is what came down the wire.
#include "drivers/centent_cn0170/cn0170_codec.hpp"
#include "drivers/copley_ascii/copley_codec.hpp"
#include "drivers/ims_party_line/ims_codec.hpp"
#include "drivers/techno_c/techno_codec.hpp"
#include "drivers/whedco_cmc/whedco_codec.hpp"
#include "fuzz/fuzz_input.hpp"

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <functional>
#include <regex>
#include <string>
#include <string_view>
#include <vector>

namespace {

using fieldgate::fuzz::split_frames;

// The Copley reply grammar of the guide's transcripts, written apart from the parser: an
// optional stray LF, `ok` or a tag (v, r, e), at most one space, integers one space apart
// (decimal or 0x-hex, optional minus; one for r and e), an optional LF, the CR.
bool copley_grammar(std::string_view line, std::vector<int64_t>& values) {
  if (line.empty() || line.back() != '\r') return false;
  line.remove_suffix(1);
  if (!line.empty() && line.back() == '\n') line.remove_suffix(1);
  if (!line.empty() && line.front() == '\n') line.remove_prefix(1);
  if (line == "ok") return true;
  if (line.size() < 2 || std::string_view("vre").find(line[0]) == std::string_view::npos)
    return false;
  const char tag = line[0];
  std::string text(line.substr(line[1] == ' ' ? 2 : 1));
  std::size_t at = 0;
  while (true) {
    const std::size_t start = at;
    if (at < text.size() && text[at] == '-') ++at;
    const bool hex = text.compare(at, 2, "0x") == 0 && at + 2 < text.size() &&
                     std::isxdigit(static_cast<unsigned char>(text[at + 2]));
    if (hex) at += 2;
    const std::size_t digits = at;
    while (at < text.size() && (hex ? std::isxdigit(static_cast<unsigned char>(text[at]))
                                    : std::isdigit(static_cast<unsigned char>(text[at]))))
      ++at;
    if (at == digits) return false;
    errno = 0;
    const long long v =
        std::strtoll(text.substr(start, at - start).c_str(), nullptr, hex ? 16 : 10);
    if (errno == ERANGE) return false;
    values.push_back(v);
    if (at == text.size()) break;
    if (text[at] != ' ') return false;
    ++at;
  }
  return tag == 'v' || values.size() == 1;
}

void copley(std::string_view wire) {
  split_frames(wire, fieldgate::copley::frame_length, [](std::string_view line) {
    const auto reply = fieldgate::copley::parse_reply(line);
    if (reply.kind == fieldgate::copley::ParsedReply::Kind::malformed) return;
    // Every reply the parser accepts is one the guide allows, with the values it prints.
    std::vector<int64_t> values;
    FUZZ_CHECK(copley_grammar(line, values));
    FUZZ_CHECK(values == reply.values);
  });
}

void ims(std::string_view wire, char name) {
  split_frames(wire, fieldgate::ims::line_length, [name](std::string_view line) {
    (void)fieldgate::ims::is_blank_line(line);
    (void)fieldgate::ims::parse_result(line);
    (void)fieldgate::ims::match_echo(name, "V", line);
    (void)fieldgate::ims::printable(line);
  });
}

void centent(std::string_view wire) {
  split_frames(wire, fieldgate::cn0170::frame_length,
               [](std::string_view line) { (void)fieldgate::cn0170::parse_message(line); });
}

// The Techno C-series reply grammar, written apart from the parser from the manual (p.29,
// p.43, p.54, p.90, p.93) and its digest (§1.2, §5, §6): a command is answered by one handshake
// character, "0 if the line was accepted" or an error character (2-8, B, c, D, G, z, CR). `@0P`
// answers "a series of eighteen characters giving the absolute position using hexadecimal
// notation in 2's complement", 6 per axis X Y Z; whether the `0` handshake comes first and a CR
// (or LF) after is not said (digest §5), nor the length for one or two axes: the family reads 6
// or 12 digits as X or X Y, the other axes 0, from a controller with that many axes fitted (the
// model's fitted_axes; 18 digits from any), and hex letters in either case (its README; the
// manual's symbols are 0-9 A-F, and a lower-case letter means the same digit). `@0b`/`@0c`
// answer "the software handshake, followed by two digits ... expressed as a hexadecimal"
// (p.54), a CR or LF possibly after.
enum class TechnoReply { handshake, positions, peek };

bool techno_grammar(std::string_view frame, TechnoReply kind, int fitted_axes,
                    std::vector<int64_t>& values) {
  if (kind == TechnoReply::handshake) return frame == "0";
  const auto positions_of = [](int axes) {
    return std::regex("0?([0-9A-Fa-f]{18}|[0-9A-Fa-f]{" + std::to_string(6 * axes) +
                      "})(?:\r\n|\r|\n)?");
  };
  static const std::regex positions[] = {positions_of(1), positions_of(2), positions_of(3)};
  static const std::regex peek("0([0-9A-Fa-f]{2})(?:\r\n|\r|\n)?");
  std::match_results<std::string_view::const_iterator> m;
  if (!std::regex_match(frame.begin(), frame.end(), m,
                        kind == TechnoReply::positions ? positions[fitted_axes - 1] : peek))
    return false;
  const std::string digits = m[1].str();
  if (kind == TechnoReply::peek) {
    values.push_back(std::stoll(digits, nullptr, 16));
    return true;
  }
  // 24-bit two's complement: 800000..FFFFFF are -8388608..-1 (p.95, corrected in digest §10.13).
  for (std::size_t at = 0; at < digits.size(); at += 6) {
    const long long v = std::stoll(digits.substr(at, 6), nullptr, 16);
    values.push_back(v >= 0x800000 ? v - 0x1000000 : v);
  }
  values.resize(3, 0);
  return true;
}

void techno(std::string_view wire, std::uint8_t mode) {
  using namespace fieldgate::techno;
  TechnoReply kind = TechnoReply::handshake;
  const int fitted_axes = 3 - mode / 9 % 3;  // the model's fitted_axes
  std::function<std::size_t(std::string_view)> split = handshake_frame;
  std::function<ParsedReply(std::string_view)> parse = parse_handshake;
  switch (mode % 3) {
    case 0:
      break;
    case 1: {
      const auto reply = static_cast<PositionReply>(mode / 3 % 3);
      kind = TechnoReply::positions;
      split = [reply](std::string_view b) { return position_frame(b, reply); };
      parse = [fitted_axes](std::string_view f) { return parse_positions(f, fitted_axes); };
      break;
    }
    default:
      kind = TechnoReply::peek;
      split = peek_frame;
      parse = parse_peek;
  }
  // Every reply the parser accepts is one the manual allows, with the values it prints; an
  // error is one of the manual's error characters.
  const auto check = [&](std::string_view frame) {
    const ParsedReply reply = parse(frame);
    if (reply.kind == ParsedReply::Kind::malformed) return;
    if (reply.kind == ParsedReply::Kind::error) {
      FUZZ_CHECK(std::string_view("2345678BcDGz\r").find(reply.code) != std::string_view::npos);
      FUZZ_CHECK(!frame.empty() && frame.front() == reply.code);
      return;
    }
    std::vector<int64_t> values;
    FUZZ_CHECK(techno_grammar(frame, kind, fitted_axes, values));
    FUZZ_CHECK(values == reply.values);
  };
  split_frames(wire, split, check);
  // A query's reply may end without a terminator: the family then parses what came before the
  // idle gap (TechnoFamily::transact_node), which no splitter has cut.
  std::string_view rest = wire;
  while (const std::size_t n = rest.empty() ? 0 : split(rest)) rest.remove_prefix(n);
  if (!rest.empty()) check(rest);
}

void whedco(std::string_view wire, std::uint8_t mode) {
  using namespace fieldgate::whedco;
  const auto echo = static_cast<EchoMode>(mode % 3);
  const std::string line = sent_line(mode / 3 % 8, "RP");
  split_frames(
      wire, [&](std::string_view b) { return frame_length(b, line, echo); },
      [&](std::string_view frame) {
        bool echoed = false;
        const std::string_view body = strip_echo(frame, line, echoed);
        (void)parse_numbers(body, mode & 0x40);
        (void)parse_bit_string(body);
        (void)axis_fault_from_text(body);
        (void)unit_fault_from_text(body);
      });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fieldgate::fuzz::Input input(data, size);
  const std::uint8_t family = input.byte();
  const std::uint8_t mode = input.byte();
  const std::string_view wire = input.rest();
  switch (family % 5) {
    case 0:
      copley(wire);
      break;
    case 1:
      ims(wire, static_cast<char>('A' + mode % 26));
      break;
    case 2:
      centent(wire);
      break;
    case 3:
      techno(wire, mode);
      break;
    default:
      whedco(wire, mode);
  }
  return 0;
}
