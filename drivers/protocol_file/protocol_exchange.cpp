#include "drivers/protocol_file/protocol_exchange.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "drivers/printable_bytes.hpp"

namespace fieldgate::protocol_file {

namespace {

Reply garbled(std::string text) {
  return Reply::of(Reply::Status::garbled, std::move(text));
}

std::size_t echo_length(const ProtocolSpec& spec, std::string_view request,
                        std::string_view input) {
  if (spec.echo == ProtocolSpec::Echo::none) return 0;
  if (input.starts_with(request)) return request.size();
  return 0;
}

bool flag_set(const FlagSpec& flag, const Capture& c) {
  bool set;
  if (flag.bit) {
    set = (c.value >> *flag.bit) & 1;
  } else {
    set = std::find(flag.values.begin(), flag.values.end(), c.value) != flag.values.end();
    if (flag.negate) set = !set;
  }
  return set;
}

}  // namespace

std::optional<std::string> encode_request(const ProtocolSpec& spec, const CommandSpec& command,
                                          const std::vector<int64_t>& arguments,
                                          std::string_view address, std::string& why) {
  auto body = command.request.render(arguments, address, why);
  if (!body) return std::nullopt;
  if (spec.checksum)
    *body += encode_checksum(*spec.checksum, compute_checksum(*spec.checksum, *body));
  return *body + spec.send_terminator;
}

FrameSplitter reply_splitter(const ProtocolSpec& spec, std::string request, std::size_t prompts) {
  return [&spec, request = std::move(request), prompts](std::string_view input) -> std::size_t {
    std::size_t start = 0;
    if (spec.echo != ProtocolSpec::Echo::none) {
      // Until the echo could be told apart, wait for more.
      if (input.size() < request.size() && std::string_view(request).starts_with(input)) return 0;
      start = echo_length(spec, request, input);
    }
    if (spec.reply_length > 0) {
      const std::size_t need = start + spec.reply_length + spec.reply_terminator.size();
      return input.size() >= need ? need : 0;
    }
    // The reply ends after its last prompt, or at the first refusal before it.
    std::size_t at = start;
    for (std::size_t n = 0; n < prompts; ++n) {
      const auto end = input.find(spec.reply_terminator, at);
      if (!spec.error_terminator.empty()) {
        const auto refused = input.find(spec.error_terminator, at);
        if (refused != std::string_view::npos && (end == std::string_view::npos || refused < end))
          return refused + spec.error_terminator.size();
      }
      if (end == std::string_view::npos) return 0;
      at = end + spec.reply_terminator.size();
    }
    return at;
  };
}

std::string error_text(const ProtocolSpec& spec, const Capture& code) {
  if (auto it = spec.error_texts.find(code.text); it != spec.error_texts.end()) return it->second;
  if (code.type != FieldType::character && code.type != FieldType::text)
    if (auto it = spec.error_texts.find(std::to_string(code.value)); it != spec.error_texts.end())
      return it->second;
  return {};
}

ReplyReading interpret_reply(const ProtocolSpec& spec, const CommandSpec& command,
                             std::string_view request, std::string_view frame,
                             std::string_view address) {
  ReplyReading r;
  std::string_view line = frame;
  const std::size_t echo = echo_length(spec, request, line);
  if (spec.echo == ProtocolSpec::Echo::always && echo == 0) {
    r.reply = garbled(fmt::format("no echo of '{}' before '{}'", printable_bytes(request),
                                  printable_bytes(frame)));
    return r;
  }
  line.remove_prefix(echo);
  if (!spec.error_terminator.empty() && line.ends_with(spec.error_terminator)) {
    line.remove_suffix(spec.error_terminator.size());
    std::string_view text = line;
    // On a line of several commands, the prompts before the refusal are those the line's first
    // commands took.
    std::size_t taken = 0;
    if (command.prompts() > 1)
      for (auto at = text.find(spec.reply_terminator); at != std::string_view::npos;
           at = text.find(spec.reply_terminator), ++taken)
        text.remove_prefix(at + spec.reply_terminator.size());
    while (!text.empty() && (text.front() == '\r' || text.front() == '\n' || text.front() == ' '))
      text.remove_prefix(1);
    if (text.starts_with(spec.reply_prefix)) text.remove_prefix(spec.reply_prefix.size());
    while (!text.empty() && (text.back() == '\r' || text.back() == '\n' || text.back() == ' '))
      text.remove_suffix(1);
    r.line = std::string(line);
    r.refusal_without_code = true;
    const std::string where =
        command.prompts() > 1
            ? fmt::format(" at command {} of {} on its line", taken + 1, command.prompts())
            : "";
    r.reply = Reply::of(Reply::Status::device_error,
                        fmt::format("{} refused{}{}", command.name, where,
                                    text.empty() ? "" : ": " + printable_bytes(text)),
                        kRefusedReply);
    return r;
  }
  if (!spec.reply_terminator.empty()) {
    if (!line.ends_with(spec.reply_terminator)) {
      r.reply =
          garbled(fmt::format("'{}' does not end in the reply terminator", printable_bytes(frame)));
      return r;
    }
    line.remove_suffix(spec.reply_terminator.size());
  }
  if (spec.unsolicited) {
    std::string ignored;
    if (spec.unsolicited->match(line, address, ignored)) {
      r.kind = ReplyReading::Kind::unsolicited;
      r.line = std::string(line);
      return r;
    }
  }
  if (spec.checksum && spec.checksum_on_replies) {
    const std::size_t n = checksum_length(*spec.checksum);
    if (line.size() < n) {
      r.reply = garbled(fmt::format("'{}' is shorter than its checksum", printable_bytes(frame)));
      return r;
    }
    const auto body = line.substr(0, line.size() - n);
    const auto sent = line.substr(line.size() - n);
    const auto expected = encode_checksum(*spec.checksum, compute_checksum(*spec.checksum, body));
    if (sent != expected) {
      r.reply = garbled(fmt::format("checksum of '{}' is '{}', not '{}'", printable_bytes(body),
                                    printable_bytes(sent), printable_bytes(expected)));
      return r;
    }
    line = body;
  }
  r.line = std::string(line);
  // A reply of several parts has the prefix in its pattern, before each part with text.
  const bool has_text = !command.reply || command.reply_has_text();
  if (!spec.reply_prefix.empty() && has_text && command.prompts() == 1) {
    if (!line.starts_with(spec.reply_prefix)) {
      r.reply = garbled(fmt::format("'{}' does not start with '{}'", printable_bytes(line),
                                    printable_bytes(spec.reply_prefix)));
      return r;
    }
    line.remove_prefix(spec.reply_prefix.size());
  }
  if (spec.error_reply) {
    std::string ignored;
    if (auto refusal = spec.error_reply->match(line, address, ignored)) {
      Capture code{}, text{};
      for (const auto& c : *refusal) {
        if (c.name == spec.error_reply_code) code = c;
        if (c.name == spec.error_reply_text) text = c;
      }
      std::string meaning = text.text.empty() ? error_text(spec, code) : text.text;
      r.from_error_reply = true;
      r.refusal_without_code = spec.error_reply_code.empty();
      r.captures = *refusal;
      r.reply = Reply::of(Reply::Status::device_error,
                          fmt::format("{} refused: {}{}", command.name, printable_bytes(line),
                                      meaning.empty() ? "" : " (" + meaning + ")"),
                          spec.error_reply_code.empty() ? kRefusedReply : code.value);
      return r;
    }
  }
  if (!command.reply) {
    r.reply = garbled(fmt::format("'{}' to {}, which the device does not answer",
                                  printable_bytes(line), command.name));
    return r;
  }
  std::string why;
  auto captures = command.reply->match(line, address, why);
  if (!captures) {
    r.reply = garbled(fmt::format("'{}' is no reply to {} ('{}'): {}", printable_bytes(line),
                                  command.name, command.reply->source(), why));
    return r;
  }
  r.captures = *captures;
  const auto find = [&](const std::string& name) -> const Capture* {
    for (const auto& c : r.captures)
      if (c.name == name) return &c;
    return nullptr;
  };
  if (command.error) {
    const Capture* code = find(command.error->capture);
    const bool ok =
        code && std::any_of(command.error->ok.begin(), command.error->ok.end(),
                            [&](const CaptureValue& v) { return capture_equals(*code, v); });
    if (!ok && code) {
      std::string text = error_text(spec, *code);
      if (!command.error->text_capture.empty())
        if (const Capture* t = find(command.error->text_capture)) text = t->text;
      r.reply = Reply::of(Reply::Status::device_error,
                          fmt::format("{} error {}{}", command.name, printable_bytes(code->text),
                                      text.empty() ? "" : ": " + text),
                          code->value);
      return r;
    }
  }
  r.reply = Reply::of(Reply::Status::ok);
  for (const auto& c : r.captures) r.reply.values.push_back(c.value);
  if (!command.flags.empty()) {
    int64_t word = 0;
    for (std::size_t k = 0; k < command.flags.size(); ++k)
      if (const Capture* c = find(command.flags[k].capture); c && flag_set(command.flags[k], *c))
        word |= int64_t{1} << k;
    r.reply.values.push_back(word);
  }
  return r;
}

Reply explain_refusal(const ProtocolSpec& spec, const CommandSpec& query, const Reply& refusal,
                      const ReplyReading& answer) {
  const bool reported = answer.reply.status == Reply::Status::device_error &&
                        !answer.from_error_reply && !answer.refusal_without_code && query.error;
  const Capture* code = nullptr;
  const Capture* text = nullptr;
  if (reported)
    for (const auto& c : answer.captures) {
      if (c.name == query.error->capture) code = &c;
      if (c.name == query.error->text_capture) text = &c;
    }
  if (code) {
    const std::string meaning = text ? text->text : error_text(spec, *code);
    return Reply::of(
        Reply::Status::device_error,
        fmt::format("{}; {} reports error {}{}", refusal.text, query.name,
                    printable_bytes(code->text), meaning.empty() ? "" : ": " + meaning),
        code->value);
  }
  const std::string why = answer.reply.status == Reply::Status::ok
                              ? fmt::format("{} reports no error", query.name)
                              : fmt::format("{} gave none: {} ({})", query.name,
                                            to_string(answer.reply.status), answer.reply.text);
  return Reply::of(Reply::Status::device_error,
                   fmt::format("{}; the device's code is unknown: {}", refusal.text, why),
                   kRefusalUnexplained);
}

Reply judge_confirmation(const ProtocolSpec&, const CommandSpec& confirmed,
                         const std::vector<int64_t>& arguments, const ConfirmStep& step,
                         const ReplyReading& confirmation) {
  if (confirmation.reply.status != Reply::Status::ok) {
    Reply r = confirmation.reply;
    if (r.status == Reply::Status::device_error)
      r.text = fmt::format("{} refused: {}", confirmed.name, r.text);
    return r;
  }
  if (step.capture.empty()) return Reply::of(Reply::Status::ok);
  const Capture* c = nullptr;
  for (const auto& x : confirmation.captures)
    if (x.name == step.capture) c = &x;
  if (!c)
    return garbled(fmt::format("{}: no {} in the confirmation", confirmed.name, step.capture));
  if (!step.equals.empty()) {
    const auto params = confirmed.parameters();
    const auto at = std::find(params.begin(), params.end(), step.equals) - params.begin();
    if (static_cast<std::size_t>(at) < arguments.size() && c->value == arguments[at])
      return Reply::of(Reply::Status::ok);
    return Reply::of(Reply::Status::device_error,
                     fmt::format("{} not taken: {} reads back {}, not the {} sent", confirmed.name,
                                 step.command, printable_bytes(c->text), step.equals),
                     kNotTaken);
  }
  if (std::find(step.in.begin(), step.in.end(), c->value) != step.in.end())
    return Reply::of(Reply::Status::ok);
  return Reply::of(Reply::Status::device_error,
                   fmt::format("{} not taken: {} reads {} = {} after it", confirmed.name,
                               step.command, step.capture, printable_bytes(c->text)),
                   kNotTaken);
}

}  // namespace fieldgate::protocol_file
