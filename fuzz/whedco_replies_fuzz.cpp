// Whedco CMC replies: every frame interpret_whedco_reply() accepts (status ok) must have the
// form the manual and the family's README allow, else the target aborts. The grammar below is
// written from them, not from the parser: blanks (space, CR, LF; tab tolerated) around the
// parts, the echo of the line sent (with or without the address digit, either letter case),
// then the reply text and the `*` prompt; numbers decimal with an optional sign and point, hex
// and status words in upper-case hex digits, binary status words of 8 or 16 digits, one upper-
// case label (`V1=`, `X:`) in front. The first input byte picks the exchange (byte % 5 the
// command, byte / 8 % 3 the echo mode, bit 7 a unit known to print hex status words), the rest
// is the wire.
#include <regex>
#include <string>
#include <string_view>
#include <utility>

#include "drivers/whedco_cmc/whedco_family.hpp"
#include "fuzz/fuzz_input.hpp"

namespace {

using fieldgate::NumberFormat;
using fieldgate::Reply;
using fieldgate::Request;
using fieldgate::WhedcoExchange;
namespace whedco = fieldgate::whedco;

const std::string kBlank = "[ \\t\\r\\n]";
const std::string kDecimal = "[+-]?(?:[0-9]+(?:\\.[0-9]*)?|\\.[0-9]+)";
const std::string kHex = "[0-9A-F]+";
const std::string kLabel = "(?:[A-Z][A-Z0-9]*[=:]" + kBlank + "*)?";

std::string numbers(const std::string& number) {
  return kLabel + number + "(?:" + kBlank + "+" + number + ")*";
}

// The echo of `line` as the README allows it: the address digit optional, any letter case.
std::string echo_of(const std::string& line) {
  std::string out = "(?:" + line.substr(0, 1) + ")?";
  for (const char c : line.substr(1)) {
    if (c >= 'A' && c <= 'Z')
      out += std::string("[") + c + static_cast<char>(c - 'A' + 'a') + "]";
    else if (std::string_view("^$\\.*+?()[]{}|").find(c) != std::string_view::npos)
      out += std::string("\\") + c;
    else  // a digit or `=` as it is: an escaped digit is a back-reference (`\1`)
      out += c;
  }
  return out;
}

struct Case {
  const char* command;
  whedco::QueryKind kind;
  Request::Expect expect;
  NumberFormat format;
  std::string body;  // the grammar of the reply text
  std::regex form;   // the whole frame: blanks, the echo if any, the body, blanks, the prompt

  Case(const char* command_, whedco::QueryKind kind_, Request::Expect expect_, NumberFormat format_,
       std::string body_)
      : command(command_),
        kind(kind_),
        expect(expect_),
        format(format_),
        body(std::move(body_)),
        form("^" + kBlank + "*(?:" + echo_of(whedco::sent_line(4, command)) + kBlank + "*)?" +
             body + kBlank + "*\\*$") {}
};

const Case& pick(std::uint8_t which) {
  // Compiled once: a regex per input made the target slow.
  static const Case cases[] = {
      {"HT", whedco::QueryKind::plain, Request::Expect::ack, NumberFormat::decimal, ""},
      {"RPX", whedco::QueryKind::plain, Request::Expect::values, NumberFormat::decimal,
       numbers(kDecimal)},
      {"V1=?", whedco::QueryKind::plain, Request::Expect::values, NumberFormat::hex, numbers(kHex)},
      {"RSX", whedco::QueryKind::status_word, Request::Expect::values, NumberFormat::decimal,
       "(?:[01]{8}|[01]{16}|[0-9A-F]{1,4}|[0-9]{1,5})"},
      {"RDI", whedco::QueryKind::bit_list, Request::Expect::values, NumberFormat::decimal,
       "(?:[01]{8,63}|" + numbers(kDecimal) + ")"},
  };
  return cases[which % (sizeof cases / sizeof cases[0])];
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fieldgate::fuzz::Input input(data, size);
  const std::uint8_t mode = input.byte();
  const Case& c = pick(mode);
  WhedcoExchange x;
  x.line = whedco::sent_line(4, c.command);
  x.mode = static_cast<whedco::EchoMode>(mode / 8 % 3);
  x.expect = c.expect;
  x.format = c.format;
  x.kind = c.kind;
  if (mode & 0x80) x.status_form = whedco::StatusForm::hex;
  fieldgate::fuzz::split_frames(
      input.rest(), [&](std::string_view b) { return whedco::frame_length(b, x.line, x.mode); },
      [&](std::string_view frame) {
        const Reply r = fieldgate::interpret_whedco_reply(x, frame);
        if (r.status != Reply::Status::ok) return;
        FUZZ_CHECK(std::regex_match(frame.begin(), frame.end(), c.form));
      });
  return 0;
}
