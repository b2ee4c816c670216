// IMS indexer replies on the party line: every reply interpret_ims_reply() accepts (status ok)
// must have the form the manual and the family's README allow, else the target aborts. The
// grammar below is written from them, not from the parser: blank lines (CR/LF only) before the
// echo; the echo of the command sent, with or without the name; for a query its result, space
// padded decimal numbers with an optional sign and at most two decimals, either on the echo's
// line or on the next non-blank line; every line ended by LF (a CR before it allowed). The first
// input byte picks the request and the name, the rest is the wire.
#include <regex>
#include <string>

#include "drivers/ims_party_line/ims_family.hpp"
#include "fuzz/fuzz_input.hpp"

namespace {

using fieldgate::NodeAddress;
using fieldgate::NumberFormat;
using fieldgate::Reply;
using fieldgate::Request;

const std::string kBlankLines = "(?:\\r*\\n)*";
const std::string kResult = " *[+-]?[0-9]+(?:\\.[0-9]{1,2})?(?: +[+-]?[0-9]+(?:\\.[0-9]{1,2})?)* *";

std::string escaped(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9'))) out += '\\';
    out += c;
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fieldgate::fuzz::Input input(data, size);
  const std::uint8_t mode = input.byte();
  static const char* const kCommands[] = {"Z", "^", "]0", "A129", "+100", "V2000"};
  const std::string command = kCommands[mode % 6];
  const bool query = mode % 6 < 4;
  const char name = static_cast<char>('A' + mode / 8 % 26);
  const NodeAddress node{std::string(1, name), static_cast<unsigned char>(name), 0};
  const Request request{command, query ? Request::Expect::values : Request::Expect::ack,
                        NumberFormat::decimal};
  const std::string_view wire = input.rest();
  const Reply r = fieldgate::interpret_ims_reply(node, request, wire);
  if (r.status != Reply::Status::ok) return 0;
  const std::string echo = "\\r*(?:" + escaped(std::string(1, name)) + ")?" + escaped(command);
  const std::string form = query ? kBlankLines + echo + "(?:" + kResult + "\\r?\\n|" + " *\\r?\\n" +
                                       kBlankLines + kResult + "\\r?\\n)"
                                 : kBlankLines + echo + " *\\r?\\n";
  static std::string last_form;
  static std::regex re;
  if (form != last_form) {
    re = std::regex("^" + form);
    last_form = form;
  }
  FUZZ_CHECK(
      std::regex_search(wire.begin(), wire.end(), re, std::regex_constants::match_continuous));
  return 0;
}
