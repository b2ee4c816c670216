#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate::cn0170 {

// Centent CN0170 host protocol (shared/protocols/centent-cn0170.md): pure functions, no I/O.
// Host lines end with CR; `;` separates instructions inside a line (§1). Replies are lines
// ended by CR and/or LF, prefixed with the sender's unit digit except from unit 0 (§2 rule 7).

inline constexpr int kMaxUnit = 9;

// Config address "0".."9".
std::optional<int> parse_unit_address(std::string_view text, std::string& error);

// ".U2\r": select a unit; every unit sees it, so it takes no prefix and gets no reply.
std::string encode_select(int unit);

// Length of the first line in buf (up to and including its CR or LF), 0 while none has ended.
// A CRLF pair therefore reads as a line and an empty line.
std::size_t frame_length(std::string_view buf);

// Instructions of a request, split at ';' and trimmed of spaces; empty ones dropped.
std::vector<std::string> split_instructions(std::string_view request);

enum class MessageKind {
  blank,             // empty line (second half of CRLF, stray terminators)
  position,          // X=00C0E6B6h / X+…h / XP=…h        values: raw, status word
  velocity,          // XV=0D485h, XYV=…h                  values: raw (0.25 steps/s)
  acceleration,      // XA=00BBh                           values: raw (64 steps/s²)
  profile,           // XC=3, XC=L/P/U                     values: 1..16, 17 L, 18 P, 19 U
  ratio,             // Y/X=80000000h                      values: raw (1/2^32)
  io,                // P1=0 .. P4=1                       values: 0/1
  aux,               // P= 3Ch                             values: bits
  analog,            // A\X=C0h, A1=…h                     values: 0..255
  mode,              // M1, M2, M3                         values: mode
  time,              // 08:45.11                           values: h, m, s
  date,              // 02/15/97                           values: month, day, year
  unit_list,         // [U5], answer to .U?                subject = 5
  autobaud,          // U3: answer to the first CR after a reset; subject = 3
  reject,            // "XY?" ?: the unit ignored that string
  queue_full,        // Q*: warning mode, queue within 1–2 instructions of full
  queue_empty,       // *Q (or a lone Q, §9 #12): the Immediate Queue emptied after a Q*
  position_trigger,  // XP / YP: a move ended (XP+)
  velocity_trigger,  // XV / YV: maximum velocity reached (XV+)
  unknown,
};

std::string_view to_string(MessageKind kind);

// Bits of the status word a position reply decodes to (the X reply uses bits 0–1, the Y reply
// bits 2–3, both set bit 4), so OR-ing the words of both axes gives the unit's motion word.
inline constexpr int64_t kXMoving = 1 << 0;
inline constexpr int64_t kXCounterClockwise = 1 << 1;
inline constexpr int64_t kYMoving = 1 << 2;
inline constexpr int64_t kYCounterClockwise = 1 << 3;
inline constexpr int64_t kMoving = 1 << 4;

// One line from the chain, demultiplexed.
struct Message {
  MessageKind kind = MessageKind::unknown;
  int unit = 0;  // sender: the prefix digit, 0 when unprefixed
  bool prefixed = false;
  std::string key;   // which reply: "XP", "YP", "XV", "YV", "XYV", "XA", "XC", "Y/X", "P1",
                     // "P", "A\X", "A1", "M", "T", "D"; the axis for triggers
  int subject = -1;  // unit number inside [Un] and Un
  std::vector<int64_t> values;
  std::string text;  // the rejected string for reject; the line for unknown
};

// Lenient where the digest advises (§5): leading 0 and spaces in hex values, h or H, CR/LF and
// spaces around the line, an optional ' ' or ':' after the prefix digit, [Un]/Un with or
// without a prefix. Strict where the manual is not silent: letters and hex digits in upper case
// as printed (a lower-case one is a garbled character: `001aD303h` is no register value).
Message parse_message(std::string_view line);

// A query the family knows how to match and decode.
struct Query {
  MessageKind kind = MessageKind::unknown;
  std::string key;      // matches Message::key
  int value_count = 1;  // values its reply decodes to
  bool hex = false;     // the reply is hex (the model's read format must say so)
};

// Whether an unterminated line is the beginning of `unit`'s reply to `query` ("2Y=0000", "X+0",
// "1M"): prefix, then the reply's key and what follows a key. False when too short to tell.
bool starts_reply(std::string_view partial, int unit, const Query& query);

// "XP?" -> position/XP; nullopt for anything that is not a query of §5. Case-insensitive.
std::optional<Query> classify_query(std::string_view instruction);

// Values a read request yields: the values of each query in order, then, if any query is a
// position query, the motion word (OR of the status words).
int values_of_request(const std::vector<Query>& queries);

enum class InstructionKind {
  query,            // answered (classify_query)
  unit_command,     // .Un, .U?, .U=n, .U+m=n, .Um=n (the family manages these itself)
  unit_assignment,  // .U=n, .U+m=n, .Um=n
  kill,             // K: relayed down the chain
  quit,             // Q
  halt,             // H
  mode_immediate,   // M1
  mode_program,     // M2: from M1 it erases the stored program
  mode_operate,     // M3
  other,            // silent on success
};
InstructionKind classify_instruction(std::string_view instruction);

// The absolute point-to-point terms of a move instruction: X=n / Y=n at its start or after '&',
// ',' or '^' (linked, linear, circular forms), n in decimal steps or raw hex (…H). `raw` is the
// target in 1/1024 step as the signed 32-bit view of the register (0FFFFF060H is -4000).
struct AbsoluteTarget {
  char axis = 'X';
  int64_t raw = 0;
};
std::vector<AbsoluteTarget> absolute_targets(std::string_view instruction);

// Rewrites that let a model pass numbers for the CN0170's symbolic forms (README "Command
// rewrites"); nullopt with `error` set for a value the CN0170 does not accept:
//   XC17 / XC18 / XC19      -> XC\L / XC\P / XC\U   (XC1..XC16 unchanged, others refused)
//   XH1 XP1 XV1 XL1 XM1 XB1 -> XH+ …;   …0 -> …-
//   XRn                     -> n must be 1, 2, 10 or 125
//   X+-5 (decimal)          -> X-5
//   X+0FFFFFC00H (raw hex >= 2^31, a negative 32-bit distance) -> X-0400H
//   X=n, XP=n below 0 (decimal -n, or raw hex >= 2^31)  -> refused: the position register
//                           takes only positive numbers (p.35), X=n runs CW if n > position
std::optional<std::string> normalise_instruction(std::string_view instruction, std::string& error);
// Every instruction of a request, joined with ';'.
std::optional<std::string> normalise_request(std::string_view request, std::string& error);

}  // namespace fieldgate::cn0170
