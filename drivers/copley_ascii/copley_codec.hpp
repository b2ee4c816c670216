#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate::copley {

// Copley ASCII framing (shared/protocols/copley-ascii.md §1–3): `[N ][.a ]cmd args\r` out,
// `ok`, `v n…`, `r n` or `e code` back, each ended by CR.

// Node 0 is the amplifier on the serial port and gets no prefix; 1–127 are reached through it.
std::string encode_command(int node, char axis, std::string_view command);

// Length of the first CR-terminated line in buf, or 0 when no CR has arrived yet.
std::size_t frame_length(std::string_view buf);

struct ParsedReply {
  enum class Kind { ok, values, register_value, error, malformed };
  Kind kind = Kind::malformed;
  std::vector<int64_t> values;  // for values, register_value and error (the code)
};

// What the guide's transcripts allow: `ok`; `v`, `r` or `e`, at most one space, then decimal
// (or 0x-hex) integers, possibly negative, one space apart (several for `v` only); the CR, and a
// stray LF before or after. Anything else (tabs, double spaces, upper-case 0X, a value beyond
// 64 bits) is malformed.
ParsedReply parse_reply(std::string_view line);

// What a command can be answered with besides `e <code>` (digest §3), so that a reply that
// cannot belong to it (a late or stray one) is recognised.
struct ExpectedReply {
  enum class Kind { ok, values, register_value, none, unknown };
  Kind kind = Kind::unknown;
  // For values: how many (0: any number, e.g. 0x5f whose count the manual does not give).
  std::size_t count = 0;
};
ExpectedReply expected_reply(std::string_view command);

// App. E text for an error code, "unknown error code" for codes the manual does not list.
std::string_view error_text(int64_t code);

// Parses a node address as written in a config: "0".."127", optionally ".a"/".b"/".c".
struct Address {
  int node = 0;
  char axis = 0;
};
std::optional<Address> parse_address(std::string_view text, std::string& error);

inline constexpr int64_t kCanFailure = 32;  // e 32: forwarded node does not answer

}  // namespace fieldgate::copley
