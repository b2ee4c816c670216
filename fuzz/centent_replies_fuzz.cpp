// Centent CN0170 reply lines: every line the parser accepts (parse_message gives a kind other
// than unknown) must have the form the manual prints for that kind (digest §5, §6), else the
// target aborts. The grammar below is written from the manual, not from the parser: register
// values in upper-case hex digits with the h suffix (H tolerated, digest §5), letters in upper
// case, an optional unit prefix 1-9 (one ' ' or ':' after it tolerated, §9 #4), spaces around
// the line, a CR or LF ending it. The first input byte picks nothing; the rest is the wire.
#include <regex>
#include <string>

#include "drivers/centent_cn0170/cn0170_codec.hpp"
#include "fuzz/fuzz_input.hpp"

namespace {

using fieldgate::cn0170::MessageKind;

const std::string kPrefix = "(?:[1-9][ :]?)?";
const std::string kHex = " *[0-9A-F]{1,9}[hH]";

// The manual's form of each reply kind, the line without its terminator and surrounding spaces.
const std::regex& form_of(MessageKind kind) {
  const auto re = [](const std::string& body) { return std::regex("^" + kPrefix + body + "$"); };
  static const std::regex position = re("[XY]P?[=+-]" + kHex);
  static const std::regex velocity = re("(?:[XY]|XY)V=" + kHex);
  static const std::regex acceleration = re("[XY]A=" + kHex);
  static const std::regex profile = re("[XY]C=(?:[0-9]{1,2}|[LPU])");
  static const std::regex ratio = re("(?:X/Y|Y/X)=" + kHex);
  static const std::regex io = re("P[1-4]=[01]");
  static const std::regex aux = re("P=" + kHex);
  static const std::regex analog = re("A(?:\\\\[XY]|[12])=" + kHex);
  static const std::regex mode = re("M[123]");
  static const std::regex time = re("[0-9]{2}:[0-9]{2}\\.[0-9]{2}");
  static const std::regex date = re("[0-9]{2}/[0-9]{2}/[0-9]{2}");
  static const std::regex unit_list = re("\\[U[0-9]\\]");
  static const std::regex autobaud = re("U[0-9]");
  static const std::regex reject = re("\"[^\\r\\n]*\" *\\?");
  static const std::regex queue_full = re("Q\\*");
  static const std::regex queue_empty = re("\\*?Q");
  static const std::regex trigger = re("[XY][PV]");
  static const std::regex nothing("$^");
  switch (kind) {
    case MessageKind::position:
      return position;
    case MessageKind::velocity:
      return velocity;
    case MessageKind::acceleration:
      return acceleration;
    case MessageKind::profile:
      return profile;
    case MessageKind::ratio:
      return ratio;
    case MessageKind::io:
      return io;
    case MessageKind::aux:
      return aux;
    case MessageKind::analog:
      return analog;
    case MessageKind::mode:
      return mode;
    case MessageKind::time:
      return time;
    case MessageKind::date:
      return date;
    case MessageKind::unit_list:
      return unit_list;
    case MessageKind::autobaud:
      return autobaud;
    case MessageKind::reject:
      return reject;
    case MessageKind::queue_full:
      return queue_full;
    case MessageKind::queue_empty:
      return queue_empty;
    case MessageKind::position_trigger:
    case MessageKind::velocity_trigger:
      return trigger;
    default:
      return nothing;
  }
}

void check_line(std::string_view frame) {
  // A frame is one line: it ends at its first CR or LF.
  FUZZ_CHECK(!frame.empty() && (frame.back() == '\r' || frame.back() == '\n'));
  const auto message = fieldgate::cn0170::parse_message(frame);
  if (message.kind == MessageKind::unknown) return;
  std::string_view line = frame.substr(0, frame.size() - 1);
  while (!line.empty() && line.front() == ' ') line.remove_prefix(1);
  while (!line.empty() && line.back() == ' ') line.remove_suffix(1);
  if (message.kind == MessageKind::blank) {
    FUZZ_CHECK(line.empty());
    return;
  }
  FUZZ_CHECK(std::regex_match(line.begin(), line.end(), form_of(message.kind)));
  // A prefix names units 1-9; unit 0 sends none.
  FUZZ_CHECK(message.prefixed == (message.unit != 0));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fieldgate::fuzz::Input input(data, size);
  (void)input.byte();
  fieldgate::fuzz::split_frames(input.rest(), fieldgate::cn0170::frame_length, check_line);
  return 0;
}
