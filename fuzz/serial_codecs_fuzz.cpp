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
#include <string>
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

void techno(std::string_view wire, std::uint8_t mode) {
  using namespace fieldgate::techno;
  switch (mode % 3) {
    case 0:
      split_frames(wire, handshake_frame, [](std::string_view f) { (void)parse_handshake(f); });
      break;
    case 1: {
      const auto reply = static_cast<PositionReply>(mode / 3 % 3);
      split_frames(
          wire, [reply](std::string_view b) { return position_frame(b, reply); },
          [](std::string_view f) { (void)parse_positions(f); });
      break;
    }
    default:
      split_frames(wire, peek_frame, [](std::string_view f) { (void)parse_peek(f); });
  }
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
