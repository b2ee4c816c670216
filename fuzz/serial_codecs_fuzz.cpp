// Every serial family's frame splitter and reply interpreter on arbitrary bytes: the first
// input byte picks the family (and its mode), the rest is what came down the wire.
#include "drivers/centent_cn0170/cn0170_codec.hpp"
#include "drivers/copley_ascii/copley_codec.hpp"
#include "drivers/ims_party_line/ims_codec.hpp"
#include "drivers/techno_c/techno_codec.hpp"
#include "drivers/whedco_cmc/whedco_codec.hpp"
#include "fuzz/fuzz_input.hpp"

namespace {

using fieldgate::fuzz::split_frames;

void copley(std::string_view wire) {
  split_frames(wire, fieldgate::copley::frame_length,
               [](std::string_view line) { (void)fieldgate::copley::parse_reply(line); });
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
