#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/protocol_file/checksum.hpp"
#include "drivers/protocol_file/field_pattern.hpp"
#include "mapping/diagnostics.hpp"

namespace fieldgate::protocol_file {

// A value one of a reply's captures is compared with: text for char and text captures, a
// number for the others.
struct CaptureValue {
  std::string text;
  int64_t number = 0;
  bool is_text = false;
};

bool capture_equals(const Capture& capture, const CaptureValue& value);

// A named flag of a status reply: set when a capture has one of the values (an enumerated
// state) or when one of its bits is set (a word or bit string). Flags add one value to the
// read, after the captures: a word with flag k at bit k.
struct FlagSpec {
  std::string name;
  std::string capture;
  std::optional<int> bit;
  std::vector<int64_t> values;  // any of these (when bit is not given)
  bool negate = false;          // `not_in:` instead of `in:`
  SourceMark mark;
};

// Which capture of a reply carries the device's error code, and the values that mean "no
// error". Another value is a device error; its text comes from the error table, or from a
// text capture.
struct ErrorCheck {
  std::string capture;
  std::vector<CaptureValue> ok;
  std::string text_capture;  // optional: the reply's own message
  SourceMark mark;
};

// A query that runs after a command to prove it was taken (a controller that answers set
// commands with nothing): its reply must match, its error check pass, and, where `capture` is
// given, that capture must equal the command's argument `equals` (a read-back) or be one of
// `in` (a state the command leads to).
struct ConfirmStep {
  std::string command;
  std::string capture;
  std::string equals;  // a parameter of the confirmed command
  std::vector<int64_t> in;
  SourceMark mark;
};

struct CommandSpec {
  std::string name;
  std::string description;
  FieldPattern request;
  std::optional<FieldPattern> reply;  // nullopt: the device answers nothing
  std::vector<FlagSpec> flags;
  std::optional<ErrorCheck> error;
  std::vector<ConfirmStep> confirm;
  std::chrono::microseconds timeout{0};  // 0: the bus's reply timeout
  SourceMark mark;
  // The reply in its parts, each ended by the reply terminator (a line of several commands, each
  // answered by its prompt; a data line and then a prompt): each part's template, where it
  // starts in `reply` (the parts joined by the terminator) and where the file writes it. A bare
  // prompt the file did not write has no mark. One part for a reply of one terminator.
  struct ReplyPart {
    std::string text;
    std::size_t offset = 0;
    SourceMark mark;
  };
  std::vector<ReplyPart> reply_parts;
  // How many reply terminators end the reply.
  std::size_t prompts() const { return reply_parts.empty() ? 1 : reply_parts.size(); }
  // Whether a part of the reply has text (a reply_prefix then comes before it).
  bool reply_has_text() const;
  // The parameters the request carries, in order (its named fields).
  std::vector<std::string> parameters() const;
  // The values a read of this command yields: its reply's named captures, then the flags word.
  std::vector<std::string> value_names() const;
  // Where one of the reply's captures (or the reply's character `offset`) is written, for
  // error marks.
  SourceMark capture_mark(const Field& capture) const { return reply_mark_at(capture.offset); }
  SourceMark reply_mark_at(std::size_t offset) const;
};

// Why the command's parameter `index` (0-based) can never be sent with `value` (a char
// argument of 300, a width too small), or nullopt when it can.
std::optional<std::string> argument_problem(const CommandSpec& command, std::size_t index,
                                            int64_t value);

struct StartupStep {
  std::string command;
  std::vector<int64_t> arguments;
  bool tolerate_errors = false;  // a unit that refuses it is still used (logged)
  SourceMark mark;
  // The start-up's one bounded loop (`discover:`): the command, whose one parameter counts from
  // `from` to at most `to`, until the device refuses with `until_error` (an ESP301 finding its
  // axes until error 9). A count the device does not answer is explained by `error_query`.
  struct Discovery {
    int64_t from = 1;
    int64_t to = 1;
    int64_t until_error = 0;
    std::string error_query;  // empty: a count without a reply ends the loop as a failure
    bool nodes = false;  // the count is of node addresses: a configured node beyond it is named
  };
  std::optional<Discovery> discover;
};

struct ProtocolSpec {
  std::string name;
  std::string description;
  std::string manual;
  std::string file;
  SourceMark mark;

  // Framing.
  std::string send_terminator = "\r";
  std::string reply_terminator = "\r\n";
  // A second way a reply may end that means "refused" (Parker's error prompt): the reply is then
  // a device error whose text is the reply's (code kRefusedReply).
  std::string error_terminator;
  std::size_t reply_length = 0;  // fixed-length replies (then no terminator is looked for)
  enum class Echo { none, always, optional } echo = Echo::none;
  // Between the commands of one line (Galil's ';'), each answered by its own prompt: a command
  // whose request holds it n times is answered by n + 1 reply terminators. Empty: not declared.
  std::string command_separator;
  std::string reply_prefix;  // before every reply with text (Parker's '*')
  std::size_t max_reply = 256;

  // Addressing.
  int address_min = 0;
  int address_max = 0;
  FieldPattern address_format;  // how {addr} is written: {addr}, {addr:int(2)}, "{addr} "
  std::map<int, std::string> address_overrides;  // addresses written otherwise (Copley's 0: "")
  std::optional<FieldPattern> request_prefix;    // what goes before every command, e.g. {addr}
  std::optional<std::string> broadcast_prefix;   // the prefix of a bus-wide command, if any

  std::optional<ChecksumSpec> checksum;
  bool checksum_on_replies = true;

  std::map<std::string, std::string, std::less<>> error_texts;  // device code -> its meaning

  // A reply any command may get instead of its own that means "refused" (Copley's "e 32"):
  // the pattern, the capture with the device's code, and optionally one with its text.
  std::optional<FieldPattern> error_reply;
  std::string error_reply_code;
  std::string error_reply_text;

  // A query sent after a refusal that carries no code (the error terminator, an error_reply
  // without code): its error check's code and text become the refusal's (Galil's TC1). Empty:
  // none.
  std::string refusal_query;

  std::optional<FieldPattern> unsolicited;  // lines the device sends on its own
  std::chrono::microseconds quiet_after_unsolicited{0};

  std::vector<StartupStep> startup;
  // The proof: queries with replies, each unlike the last; a step may expect a known refusal
  // (its error reply with that code) instead of an answer.
  struct AlignmentStepSpec {
    std::string command;
    std::optional<int64_t> error;
  };
  std::vector<AlignmentStepSpec> alignment;

  std::vector<CommandSpec> commands;

  const CommandSpec* find(std::string_view command) const;
  // The node's address as the protocol writes it.
  std::string address_text(int number) const;
};

using ProtocolSpecPtr = std::shared_ptr<const ProtocolSpec>;

}  // namespace fieldgate::protocol_file
