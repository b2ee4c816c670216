#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/link.hpp"
#include "drivers/protocol_family.hpp"
#include "drivers/protocol_file/protocol_spec.hpp"

namespace fieldgate::protocol_file {

// The device code of a command whose confirmation shows that it did not take (a read-back that
// differs, a state it does not lead to); the device's own codes are its error table's.
inline constexpr int64_t kNotTaken = 0xFFFA;
// The device code of a reply that ended in the protocol's error terminator (a refusal that
// carries a message but no code).
inline constexpr int64_t kRefusedReply = 1;
// The device code of a refusal the file's refusal_query could not explain (it failed, or
// reported no error): the device's own code is unknown.
inline constexpr int64_t kRefusalUnexplained = 0xFFF8;

// The I/O-free parts of one exchange with a protocol-file device (drivers/README.md, "The shape
// of a stream family's exchange"): what goes on the wire, how a reply is framed, and what a
// framed reply means. The family's transact() is the glue.

// The request's bytes: the command with its arguments and the node's address (or the
// broadcast prefix), the checksum, the send terminator. nullopt with `why` for an argument the
// command's field cannot carry.
std::optional<std::string> encode_request(const ProtocolSpec& spec, const CommandSpec& command,
                                          const std::vector<int64_t>& arguments,
                                          std::string_view address, std::string& why);

// Frames one reply: the echo of `request` first where the protocol echoes (always; or when
// the input starts with it, optional), then the reply up to its terminator or fixed length; a
// reply of several prompts (CommandSpec::prompts) up to the last, or to an error terminator
// before it.
FrameSplitter reply_splitter(const ProtocolSpec& spec, std::string request,
                             std::size_t prompts = 1);

// What a framed reply is.
struct ReplyReading {
  enum class Kind { reply, unsolicited } kind = Kind::reply;
  Reply reply;                    // when kind is reply: ok (with values), device_error, garbled
  std::vector<Capture> captures;  // of an ok reply (and of a device error), for confirmations
  std::string line;               // the reply without echo, prefix, checksum and terminator
  bool from_error_reply = false;  // the device error is the protocol's error_reply
  // A refusal that carries no code of its own (the error terminator, an error_reply without
  // code): the file's refusal_query may explain it.
  bool refusal_without_code = false;
};

ReplyReading interpret_reply(const ProtocolSpec& spec, const CommandSpec& command,
                             std::string_view request, std::string_view frame,
                             std::string_view address);

// Whether a confirmation's reply shows that the confirmed command was taken; the reason if
// not (a device error keeps the confirmation's code and text).
Reply judge_confirmation(const ProtocolSpec& spec, const CommandSpec& confirmed,
                         const std::vector<int64_t>& arguments, const ConfirmStep& step,
                         const ReplyReading& confirmation);

// A refusal without a code (ReplyReading::refusal_without_code) as the file's refusal query
// explains it: the code and text of the query's error check; where the query failed or reports
// no error, the refusal still stands, its code unknown (kRefusalUnexplained) and said so.
Reply explain_refusal(const ProtocolSpec& spec, const CommandSpec& query, const Reply& refusal,
                      const ReplyReading& answer);

// The meaning of a device error code from the protocol's error table, if it has one.
std::string error_text(const ProtocolSpec& spec, const Capture& code);

}  // namespace fieldgate::protocol_file
