#include "drivers/protocol_file/protocol_file_family.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "drivers/printable_bytes.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate::protocol_file {

namespace {

// A model's command text as words: literal words and placeholders, each a word of its own.
struct Word {
  std::string text;
  bool placeholder = false;
};

std::optional<std::vector<Word>> words_of(const CommandTemplate& t, std::string& error) {
  std::vector<Word> words;
  std::string current;
  bool current_open = false;
  bool right_after_placeholder = false;
  const auto end_word = [&] {
    if (current_open) words.push_back(Word{std::exchange(current, {}), false});
    current_open = false;
  };
  for (const auto& piece : t.pieces()) {
    if (!piece.name.empty()) {
      if (current_open) {
        error = fmt::format(
            "'{}': {{{}}} is part of the word '{}'; write the command's name "
            "and its arguments apart, e.g. 'move_absolute {{target}}'",
            t.source(), piece.name, current);
        return std::nullopt;
      }
      if (piece.format != 'd') {
        error = fmt::format(
            "'{}': the protocol file sets how {{{}}} is written; write it "
            "without a format",
            t.source(), piece.name);
        return std::nullopt;
      }
      words.push_back(Word{piece.name, true});
      right_after_placeholder = true;
      continue;
    }
    for (const char c : piece.literal) {
      if (c == ' ' || c == '\t') {
        end_word();
        right_after_placeholder = false;
        continue;
      }
      if (right_after_placeholder) {
        error = fmt::format("'{}': '{}' follows {{{}}} without a space", t.source(), c,
                            words.back().text);
        return std::nullopt;
      }
      current += c;
      current_open = true;
    }
  }
  end_word();
  return words;
}

Reply refused(std::string text) {
  return Reply::of(Reply::Status::device_error, "not sent: " + std::move(text), kNotSent);
}

// Lets whatever the line may still carry of a reply pass: a guard time of quiet, ten at most.
asio::awaitable<void> let_the_line_settle(Link& link, const LinkTiming& timing) {
  const auto guard = guard_time(timing, link.char_time_us());
  co_await link.resync(guard, 10 * guard);
}

std::string captures_text(const std::vector<Capture>& captures) {
  std::string s;
  for (const auto& c : captures) s += fmt::format("{}{}={}", s.empty() ? "" : " ", c.name, c.text);
  return s;
}

}  // namespace

std::optional<NodeAddress> ProtocolFileFamily::parse_address(std::string_view text,
                                                             std::string& error) const {
  const auto n = parse_integer_text(text);
  if (!n || *n < spec_->address_min || *n > spec_->address_max) {
    error = fmt::format("address '{}': {} addresses are numbers {}..{} (protocol file {})", text,
                        spec_->name, spec_->address_min, spec_->address_max, spec_->file);
    return std::nullopt;
  }
  return NodeAddress::numbered(static_cast<int>(*n));
}

std::shared_ptr<const CompiledProtocolCommand> ProtocolFileFamily::compile(
    const CommandTemplate& text, std::string& error) const {
  const auto words = words_of(text, error);
  if (!words) return nullptr;
  if (words->empty() || words->front().placeholder) {
    error = fmt::format("'{}': a command of protocol {} starts with its name", text.source(),
                        spec_->name);
    return nullptr;
  }
  const CommandSpec* command = spec_->find(words->front().text);
  if (!command) {
    std::string known;
    for (const auto& c : spec_->commands) known += (known.empty() ? "" : ", ") + c.name;
    error = fmt::format("'{}': protocol {} has no command '{}' (commands: {})", text.source(),
                        spec_->name, words->front().text, known);
    return nullptr;
  }
  const auto params = command->parameters();
  if (words->size() - 1 != params.size()) {
    error = fmt::format("'{}': {} takes {} argument(s) ({}), {} given", text.source(),
                        command->name, params.size(), command->request.source(), words->size() - 1);
    return nullptr;
  }
  auto compiled = std::make_shared<CompiledProtocolCommand>();
  compiled->spec = spec_;
  compiled->command = command;
  std::size_t placeholder = 0;
  for (std::size_t i = 1; i < words->size(); ++i) {
    const Word& w = (*words)[i];
    CompiledProtocolCommand::Argument a;
    if (w.placeholder) {
      a.placeholder = placeholder++;
    } else if (const auto v = parse_integer_text(w.text)) {
      a.constant = true;
      a.value = *v;
      if (const auto why = argument_problem(*command, i - 1, *v)) {
        error = fmt::format("'{}': {}", text.source(), *why);
        return nullptr;
      }
    } else {
      error = fmt::format("'{}': argument '{}' of {} is neither a {{placeholder}} nor an integer",
                          text.source(), w.text, command->name);
      return nullptr;
    }
    compiled->arguments.push_back(a);
  }
  return compiled;
}

// A point is a number on the register map; a text capture has no number (its value would be
// served as 0, with good quality).
void ProtocolFileFamily::check_capture_fills_point(const PointDef& point,
                                                   const CommandSpec& command,
                                                   Diagnostics& diagnostics) const {
  const auto captures = command.reply->named_fields();
  const auto field = static_cast<std::size_t>(point.read->field);
  if (field >= captures.size() || captures[field]->type != FieldType::text) return;
  const Field& f = *captures[field];
  diagnostics.error(
      point.mark,
      fmt::format("point {} read: value {} of {} is {{{}:text}} ({}: '{}'), which no {} point "
                  "can hold: capture a number there in the protocol file (int, decimal(S), hex, "
                  "char or bits(N)), or read another value of {}",
                  point.name, field, command.name, f.name, to_string(command.capture_mark(f)),
                  command.reply->source(), to_string(point.type), command.name));
}

void ProtocolFileFamily::validate_model(const Model& model, Diagnostics& diagnostics) const {
  ProtocolFamily::validate_model(model, diagnostics);
  const auto check =
      [&](const CommandTemplate& t, const SourceMark& mark,
          const std::string& what) -> std::shared_ptr<const CompiledProtocolCommand> {
    std::string error;
    auto c = compile(t, error);
    if (!c) diagnostics.error(mark, fmt::format("{}: {}", what, error));
    return c;
  };
  for (const auto& p : model.points) {
    if (p.read) {
      if (p.read->object) {
        diagnostics.error(p.mark,
                          fmt::format("point {}: objects are for the canopen family", p.name));
      } else if (auto c = check(p.read->request, p.mark, "point " + p.name + " read")) {
        const auto values = c->command->value_names();
        if (!c->command->reply || !c->arguments.empty())
          diagnostics.error(p.mark, fmt::format("point {} read: {} is no query (a read names a "
                                                "command with a reply and no arguments)",
                                                p.name, c->command->name));
        else if (p.read->field < 0 || static_cast<std::size_t>(p.read->field) >= values.size())
          diagnostics.error(p.mark, fmt::format("point {} read: field {} of {}, whose reply "
                                                "gives {} value(s): {}",
                                                p.name, p.read->field, c->command->name,
                                                values.size(), fmt::join(values, ", ")));
        else
          check_capture_fills_point(p, *c->command, diagnostics);
      }
    }
    if (p.write) {
      if (p.write->object)
        diagnostics.error(p.mark,
                          fmt::format("point {}: objects are for the canopen family", p.name));
      else
        check(p.write->request, p.mark, "point " + p.name + " write");
    }
  }
  for (const auto& a : model.actions) {
    if (a.bus_wide && !spec_->broadcast_prefix)
      diagnostics.error(a.mark, fmt::format("action {}: protocol {} has no broadcast address "
                                            "(address: broadcast)",
                                            a.name, spec_->name));
    for (const auto& s : a.steps) {
      if (s.kind != ActionStep::Kind::send) continue;
      check(s.command, s.mark, "action " + a.name);
      if (s.urgent)
        diagnostics.error(s.mark, fmt::format("action {}: a protocol file has no urgent "
                                              "commands; its exchanges never hold the line",
                                              a.name));
    }
  }
}

void ProtocolFileFamily::compile_commands(Model& model) const {
  const auto compile_into = [&](CommandTemplate& t) {
    std::string error;
    if (auto c = compile(t, error)) t.set_compiled(std::move(c));
  };
  for (auto& p : model.points) {
    if (p.read && !p.read->object) compile_into(p.read->request);  // polls: no lookup by name
    if (p.write && !p.write->object) compile_into(p.write->request);
  }
  for (auto& a : model.actions)
    for (auto& s : a.steps)
      if (s.kind == ActionStep::Kind::send) compile_into(s.command);
}

NodeContextPtr ProtocolFileFamily::bind_node(const NodeAddress& node, const Model& model) {
  nodes_.insert(node.number);
  return ProtocolFamily::bind_node(node, model);
}

std::size_t ProtocolFileFamily::estimate_wire_chars(const NodeAddress&,
                                                    const Request& request) const {
  const auto* compiled = dynamic_cast<const CompiledProtocolCommand*>(request.compiled.get());
  const CommandSpec* c = compiled ? compiled->command : spec_->find(request.command);
  if (!c) return request.command.size() + spec_->send_terminator.size() + 16;
  const std::size_t reply = c->reply ? c->reply->source().size() + 4 : 0;
  return c->request.source().size() + spec_->send_terminator.size() + reply +
         spec_->reply_terminator.size();
}

asio::awaitable<ReplyReading> ProtocolFileFamily::exchange(Link& link, const CommandSpec& command,
                                                           const std::vector<int64_t>& arguments,
                                                           std::string_view address,
                                                           const LinkTiming& timing) {
  ReplyReading reading = co_await exchange_once(link, command, arguments, address, timing);
  const bool unexplained = reading.kind == ReplyReading::Kind::reply &&
                           reading.reply.status == Reply::Status::device_error &&
                           reading.refusal_without_code;
  if (!unexplained || spec_->refusal_query.empty()) co_return reading;
  const CommandSpec* query = spec_->find(spec_->refusal_query);
  if (!query || query == &command) co_return reading;
  link.discard_input();
  const std::vector<int64_t> no_arguments;
  const ReplyReading answer = co_await exchange_once(link, *query, no_arguments, address, timing);
  reading.reply = explain_refusal(*spec_, *query, reading.reply, answer);
  const bool out_of_step = answer.reply.status == Reply::Status::timeout ||
                           answer.reply.status == Reply::Status::garbled;
  // What the line may still carry of the query's reply must not answer the next request.
  if (out_of_step) co_await let_the_line_settle(link, timing);
  co_return reading;
}

asio::awaitable<ReplyReading> ProtocolFileFamily::exchange_once(
    Link& link, const CommandSpec& command, const std::vector<int64_t>& arguments,
    std::string_view address, const LinkTiming& timing) {
  ReplyReading reading;
  std::string why;
  const auto wire = encode_request(*spec_, command, arguments, address, why);
  if (!wire) {
    reading.reply = refused(fmt::format("{}: {}", command.name, why));
    co_return reading;
  }
  if (const auto ec = co_await link.send(*wire)) {
    reading.reply = Reply::of(Reply::Status::link_down, ec.message());
    co_return reading;
  }
  link.label_last_frame(command.name);
  LinkTiming t = timing;
  if (command.timeout.count() > 0) t.reply_timeout = command.timeout;
  if (!command.reply) {
    // The echo of a command the device does not answer is all that comes back.
    if (spec_->echo == ProtocolSpec::Echo::always) {
      const std::size_t n = wire->size();
      const auto read = co_await link.read_frame(
          [n](std::string_view in) -> std::size_t { return in.size() >= n ? n : 0; }, t);
      if (read.status == LinkRead::Status::frame)
        link.label_last_frame(fmt::format("{} echo", command.name));
      if (read.status != LinkRead::Status::frame || read.frame != *wire) {
        reading.reply =
            read.status == LinkRead::Status::timeout && read.partial.empty()
                ? Reply::of(Reply::Status::timeout, fmt::format("no echo of {}", command.name))
                : Reply::of(Reply::Status::garbled,
                            fmt::format("echo of {} '{}' came back as '{}'", command.name,
                                        printable_bytes(*wire),
                                        printable_bytes(read.frame + read.partial)));
        co_return reading;
      }
    }
    reading.reply = Reply::of(Reply::Status::ok);
    co_return reading;
  }
  const auto splitter = reply_splitter(*spec_, *wire, command.prompts());
  for (int set_aside = 0;; ++set_aside) {
    const auto read = co_await link.read_frame(splitter, t);
    switch (read.status) {
      case LinkRead::Status::frame:
        break;
      case LinkRead::Status::timeout:
        reading.reply = Reply::of(Reply::Status::timeout,
                                  read.partial.empty()
                                      ? fmt::format("no reply to {}", command.name)
                                      : fmt::format("reply to {} cut short: '{}'", command.name,
                                                    printable_bytes(read.partial)));
        co_return reading;
      case LinkRead::Status::overflow:
        reading.reply = Reply::of(Reply::Status::garbled,
                                  fmt::format("reply to {} longer than any: '{}'", command.name,
                                              printable_bytes(read.partial)));
        co_return reading;
      case LinkRead::Status::error:
        reading.reply = Reply::of(Reply::Status::link_down, read.error.message());
        co_return reading;
    }
    reading = interpret_reply(*spec_, command, *wire, read.frame, address);
    const bool answered =
        reading.kind == ReplyReading::Kind::reply && reading.reply.status == Reply::Status::ok;
    if (answered || link.labels_wanted()) {
      // One description of the frame, for the trace's label and the debug log.
      const std::string said =
          reading.kind == ReplyReading::Kind::unsolicited ? std::string("unsolicited")
          : reading.captures.empty()
              ? command.name
              : fmt::format("{} {}", command.name, captures_text(reading.captures));
      link.label_last_frame(said);
      if (answered) link.note(said, 7);
    }
    if (reading.kind == ReplyReading::Kind::reply) co_return reading;
    link.note(fmt::format("the device sent '{}' on its own (unsolicited), set aside while "
                          "waiting for the reply to {}",
                          printable_bytes(reading.line), command.name),
              4);
    if (set_aside >= 8) {
      reading.kind = ReplyReading::Kind::reply;
      reading.reply = Reply::of(Reply::Status::garbled,
                                fmt::format("only unsolicited lines in reply to {}", command.name));
      co_return reading;
    }
    t.reply_timeout += spec_->quiet_after_unsolicited;
  }
}

asio::awaitable<Reply> ProtocolFileFamily::run(Link& link, const CommandSpec& command,
                                               const std::vector<int64_t>& arguments,
                                               std::string_view address, const LinkTiming& timing) {
  const auto reading = co_await exchange(link, command, arguments, address, timing);
  if (reading.reply.status != Reply::Status::ok) co_return reading.reply;
  for (const auto& step : command.confirm) {
    const CommandSpec* query = spec_->find(step.command);
    const auto confirmation = co_await exchange(link, *query, {}, address, timing);
    auto judged = judge_confirmation(*spec_, command, arguments, step, confirmation);
    if (judged.status != Reply::Status::ok) co_return judged;
  }
  co_return reading.reply;
}

ProtocolFileFamily::Resolved ProtocolFileFamily::resolve(const NodeAddress& node,
                                                         const Request& request) const {
  Resolved r;
  if (const auto* compiled = dynamic_cast<const CompiledProtocolCommand*>(request.compiled.get())) {
    r.command = compiled->command;
    for (const auto& a : compiled->arguments) {
      if (a.constant) {
        r.arguments.push_back(a.value);
      } else if (a.placeholder < request.arguments.size()) {
        r.arguments.push_back(request.arguments[a.placeholder]);
      } else {
        r.refusal = fmt::format("{}: an argument is missing", r.command->name);
        return r;
      }
    }
  } else {
    r.command = spec_->find(request.command);
    if (!r.command || !r.command->parameters().empty()) {
      r.refusal = fmt::format("'{}' is no command of protocol {} without arguments",
                              request.command, spec_->name);
      return r;
    }
  }
  if (request.bus_wide) {
    if (!spec_->broadcast_prefix) {
      r.refusal = fmt::format("protocol {} has no broadcast address", spec_->name);
      return r;
    }
    r.address = *spec_->broadcast_prefix;
  } else {
    r.address = spec_->address_text(node.number);
  }
  return r;
}

std::optional<std::string> ProtocolFileFamily::pipelined_request(NodeContext& node,
                                                                 const Request& request) {
  const Resolved r = resolve(node.address(), request);
  if (!r.refusal.empty() || request.bus_wide || !r.command->reply) return std::nullopt;
  std::string why;
  return encode_request(*spec_, *r.command, r.arguments, r.address, why);
}

asio::awaitable<Reply> ProtocolFileFamily::transact(Link& link, const NodeAddress& node,
                                                    const Request& request,
                                                    const LinkTiming& timing) {
  const Resolved r = resolve(node, request);
  if (!r.refusal.empty()) co_return refused(r.refusal);
  link.discard_input();
  co_return co_await run(link, *r.command, r.arguments, r.address, timing);
}

asio::awaitable<void> ProtocolFileFamily::discover(Link& link, const StartupStep& step,
                                                   const LinkTiming& timing) {
  const auto& d = *step.discover;
  const CommandSpec* command = spec_->find(step.command);
  int64_t found = d.from - 1;  // the last count that answered
  std::string ended;           // why the count stopped
  bool as_expected = false;
  const std::string no_address;  // the count is the parameter (checked at load)
  const std::vector<int64_t> no_arguments;
  for (int64_t n = d.from; n <= d.to; ++n) {
    link.discard_input();
    const std::vector<int64_t> count{n};
    Reply reply = co_await run(link, *command, count, no_address, timing);
    if (reply.status == Reply::Status::timeout && !d.error_query.empty()) {
      // The device does not answer a count it does not have; its error query says why.
      co_await let_the_line_settle(link, timing);
      link.discard_input();
      reply = co_await run(link, *spec_->find(d.error_query), no_arguments, no_address, timing);
      if (reply.status == Reply::Status::ok)
        reply = Reply::of(Reply::Status::timeout,
                          fmt::format("no reply, and {} reports no error", d.error_query));
    }
    if (reply.status == Reply::Status::ok) {
      found = n;
      continue;
    }
    as_expected = reply.status == Reply::Status::device_error && reply.device_code == d.until_error;
    ended = fmt::format("{} {}: {} ({})", command->name, n, to_string(reply.status), reply.text);
    break;
  }
  const std::string counted =
      found < d.from ? std::string("none") : fmt::format("{}..{}", d.from, found);
  if (as_expected || ended.empty()) {
    link.note(fmt::format("start-up: {} found {}{}", command->name, counted,
                          ended.empty() ? fmt::format(" (all up to {})", d.to)
                                        : fmt::format("; {}", ended)),
              5);
  } else {
    link.note(fmt::format("start-up: {} found {}, then stopped on what is not the end of the "
                          "count (error {}): {}",
                          command->name, counted, d.until_error, ended),
              4);
  }
  if (!d.nodes || (!as_expected && !ended.empty())) co_return;
  for (const int node : nodes_)
    if (node < d.from || node > found)
      link.note(fmt::format("start-up: node address {} is configured, but the controller "
                            "answered {} for {} only",
                            node, command->name, counted),
                4);
}

asio::awaitable<void> ProtocolFileFamily::on_link_open(Link& link, const LinkTiming& timing) {
  for (const auto& step : spec_->startup) {
    if (step.discover) {
      co_await discover(link, step, timing);
      continue;
    }
    const CommandSpec* command = spec_->find(step.command);
    std::vector<std::string> addresses;
    if (command->request.has_address()) {
      for (const int n : nodes_) addresses.push_back(spec_->address_text(n));
    } else {
      addresses.emplace_back();
    }
    for (const auto& address : addresses) {
      link.discard_input();
      const auto reply = co_await run(link, *command, step.arguments, address, timing);
      if (reply.status == Reply::Status::ok) continue;
      link.note(
          fmt::format("start-up {}{}: {} ({}){}", command->name,
                      address.empty() ? "" : " to " + address, to_string(reply.status), reply.text,
                      step.tolerate_errors ? "; tolerated, as the protocol file says" : ""),
          step.tolerate_errors ? 5 : 4);
      if (reply.status != Reply::Status::device_error) {
        // The line may still carry the rest of that reply: let it pass before the next step.
        co_await let_the_line_settle(link, timing);
      }
    }
  }
}

std::optional<AlignmentProof> ProtocolFileFamily::alignment_proof(NodeContext& node,
                                                                  const LinkTiming&) {
  AlignmentProof proof;
  const std::string address = spec_->address_text(node.address().number);
  for (const auto& spec_step : spec_->alignment) {
    const CommandSpec* command = spec_->find(spec_step.command);
    std::string why;
    const auto wire = encode_request(*spec_, *command, {}, address, why);
    if (!wire) return std::nullopt;
    const std::string expected =
        spec_step.error
            ? fmt::format("{} (error {})", spec_->error_reply->source(), *spec_step.error)
            : command->reply->source();
    if (!proof.name.empty()) proof.name += ", ";
    proof.name += fmt::format("{} -> {}", command->name, expected);
    AlignmentStep step;
    step.request = *wire;
    step.splitter = reply_splitter(*spec_, *wire, command->prompts());
    step.matches = [spec = spec_, command, request = *wire, address,
                    error = spec_step.error](std::string_view frame) {
      const auto r = interpret_reply(*spec, *command, request, frame, address);
      if (r.kind != ReplyReading::Kind::reply) return false;
      if (error)
        return r.reply.status == Reply::Status::device_error && r.from_error_reply &&
               r.reply.device_code == *error;
      return r.reply.status == Reply::Status::ok;
    };
    step.expected = expected;
    proof.steps.push_back(std::move(step));
  }
  return proof;
}

FamilyPtr make_protocol_file_family(ProtocolSpecPtr spec) {
  return std::make_shared<ProtocolFileFamily>(std::move(spec));
}

}  // namespace fieldgate::protocol_file
