#include "drivers/ims_party_line/ims_exchange.hpp"

#include <fmt/format.h>

#include "drivers/ims_party_line/ims_codec.hpp"

namespace fieldgate {

namespace {

char name_of(const NodeAddress& node) {
  return static_cast<char>(node.number);
}

std::string pin_hint(std::string_view option, std::string_view value) {
  return fmt::format(" (the model pins {}: {}; set it to auto to accept both)", option, value);
}

// A result line found where the unit's pinned result_placement says it cannot be.
std::string misplaced_result(const NodeAddress& node, ims::ResultPlacement found,
                             std::string_view line) {
  const bool on_echo_line = found == ims::ResultPlacement::echo_line;
  return fmt::format("unit {}: result {} '{}'", node.text,
                     on_echo_line ? "on the echo's line" : "on a line of its own",
                     ims::printable(line)) +
         pin_hint("result_placement",
                  ims::to_string(on_echo_line ? ims::ResultPlacement::next_line
                                              : ims::ResultPlacement::echo_line));
}

// What an echo line says, whichever reading the unit uses; nullopt: a result line follows.
std::optional<Reply> interpret_echo(const NodeAddress& node, const Request& request,
                                    const ims::EchoLine& echo, std::string_view line) {
  if (echo.match == ims::EchoMatch::mismatch)
    return Reply::of(Reply::Status::garbled,
                     fmt::format("echo '{}' does not match '{}'", ims::printable(line),
                                 ims::printable(ims::encode_line(name_of(node), request.command))));
  if (!ims::expects_result(request)) {
    if (echo.result)
      return Reply::of(
          Reply::Status::garbled,
          fmt::format("unit {}: a value '{}' after the echo of '{}', which has no "
                      "result",
                      node.text, ims::printable(echo.rest), ims::printable(request.command)));
    return Reply::of(Reply::Status::ok);
  }
  if (echo.result) {
    Reply r = Reply::of(Reply::Status::ok);
    r.values = echo.result->values;
    return r;
  }
  return std::nullopt;
}

}  // namespace

Reply interpret_ims_result(const NodeAddress& node, const Request& request, std::string_view line) {
  const auto result = ims::parse_result(line);
  if (!result)
    return Reply::of(Reply::Status::garbled,
                     fmt::format("unit {}: '{}' is no result line for '{}'", node.text,
                                 ims::printable(line), ims::printable(request.command)));
  Reply r = Reply::of(Reply::Status::ok);
  r.values = result->values;
  return r;
}

Reply interpret_ims_reply(const NodeAddress& node, const Request& request,
                          std::string_view received) {
  const auto next_line = [&](std::string_view& rest) -> std::optional<std::string_view> {
    for (int blank = 0;; ++blank) {
      const std::size_t n = ims::line_length(rest);
      if (n == 0) return std::nullopt;
      const std::string_view line = rest.substr(0, n);
      rest.remove_prefix(n);
      if (!ims::is_blank_line(line) || blank == ims::kMaxBlankLines) return line;
    }
  };
  ims::UnitReadings readings;
  ims::LateReplies late;
  ims::UnitTrack unit;
  ims::Exchange exchange(node, request, readings, late, unit, ims::Clock::duration::zero());
  const ims::Clock::time_point now{};
  std::string_view rest = received;
  if (const auto echo = next_line(rest))
    exchange.on_echo(*echo, now);
  else if (ims::is_blank_line(rest))
    exchange.on_echo_failure(Reply::of(Reply::Status::timeout, "no echo from unit " + node.text),
                             rest, now);
  else
    exchange.on_echo_failure(Reply::of(Reply::Status::garbled,
                                       fmt::format("incomplete echo '{}'", ims::printable(rest))),
                             rest, now);
  if (exchange.next() == ims::Exchange::Next::completion) exchange.on_completion(rest, now);
  if (exchange.next() == ims::Exchange::Next::result) {
    if (const auto result = next_line(rest))
      exchange.on_result(*result, now);
    else if (rest.empty())
      exchange.on_result_failure(Reply::of(Reply::Status::timeout, "no result line"), now);
    else
      exchange.on_result_failure(
          Reply::of(Reply::Status::garbled,
                    fmt::format("incomplete result line '{}'", ims::printable(rest))),
          now);
  }
  return exchange.reply();
}

}  // namespace fieldgate

namespace fieldgate::ims {

bool expects_result(const Request& request) {
  return request.expect == Request::Expect::values ||
         classify(request.command) == CommandClass::query;
}

Exchange::Exchange(const NodeAddress& node, const Request& request, UnitReadings& readings,
                   LateReplies& late, UnitTrack& unit, Clock::duration late_window)
    : node_(node),
      request_(request),
      name_(name_of(node)),
      query_(expects_result(request)),
      pins_(readings.pins(name_)),
      readings_(readings),
      late_(late),
      unit_(unit),
      late_window_(late_window) {}

void Exchange::log(int level, std::optional<std::string> text) {
  if (text) log_.push_back({level, std::move(*text)});
}

Exchange::Next Exchange::finish(Reply reply) {
  reply_ = std::move(reply);
  next_ = Next::done;
  return next_;
}

Exchange::Next Exchange::fail(Reply failure, Clock::time_point now) {
  // A unit that had answered and now is silent may only be slow: its echo may still come.
  if (failure.status == Reply::Status::timeout && unit_.answering)
    late_.silent(name_, normalize_command(request_.command), now);
  if (failure.status == Reply::Status::timeout) unit_.answering = false;
  return finish(std::move(failure));
}

Exchange::Next Exchange::on_link_down(std::string text) {
  return finish(Reply::of(Reply::Status::link_down, std::move(text)));
}

Exchange::Next Exchange::on_send_failure(Reply failure, std::string_view echoed,
                                         Clock::time_point now) {
  if (failure.status == Reply::Status::link_down) return finish(std::move(failure));
  late_.stray(echoed, now);
  return fail(std::move(failure), now);
}

Reply Exchange::single_mode_reply(Reply failure, std::string_view partial) {
  if (!single_mode_echo(name_, request_.command, partial)) {
    unit_.single_mode_echoes = 0;
    return failure;
  }
  if (++unit_.single_mode_echoes < 2) return failure;
  // The mode is the Party input's level at reset (p.5, 10): no command switches it.
  const std::string what = fmt::format(
      "unit {} answers as an indexer in Single mode: it echoed '{}' with the name and without "
      "the LF, {} times in a row (in Single mode every character is echoed and only CR ends a "
      "line, p.10-11; after a reset it waits for a Space and takes the first character as its "
      "name). The mode is read from the Party input at reset: ground the Party input and "
      "power-cycle the unit. Nothing the gateway sends is executed until then",
      node_.text, printable(partial), unit_.single_mode_echoes);
  if (unit_.single_mode_echoes == 2) log(4, what);
  failure.text = what;
  return failure;
}

Exchange::Next Exchange::on_echo_failure(Reply failure, std::string_view partial,
                                         Clock::time_point now) {
  if (failure.status == Reply::Status::link_down) return finish(std::move(failure));
  failure = single_mode_reply(std::move(failure), partial);
  // A query's echo that stopped before its LF: the rest (its result) may still come.
  if (query_ && failure.status == Reply::Status::garbled &&
      parse_echo_line(name_, request_.command, std::string(partial) + "\n").match !=
          EchoMatch::mismatch)
    late_.owe_result(now);
  return fail(std::move(failure), now);
}

Exchange::Next Exchange::on_echo(std::string_view line, Clock::time_point now) {
  unit_.single_mode_echoes = 0;
  const EchoLine parsed = parse_echo_line(name_, request_.command, line);
  if (parsed.match == EchoMatch::mismatch) late_.stray(line, now);
  // A value after a non-query's echo is the rest of another unit's late line.
  if (!query_ && parsed.result) late_.pay();
  if (auto early = interpret_echo(node_, request_, parsed, line);
      early && early->status != Reply::Status::ok)
    return fail(std::move(*early), now);

  const bool with_name = parsed.match == EchoMatch::with_name;
  if (!with_name) {
    // Without the name, the echo could be another unit's late echo of the same command.
    if (readings_.echoes_name(name_) == true)
      return fail(Reply::of(Reply::Status::garbled,
                            fmt::format("unit {} echoes its name, but '{}' came without it: "
                                        "another unit's late echo?",
                                        node_.text, printable(line))),
                  now);
    if (late_.suspicious(name_, normalize_command(request_.command), now, late_window_))
      return fail(Reply::of(Reply::Status::garbled,
                            fmt::format("echo '{}' without a name may be the late echo of a unit "
                                        "that went silent on the same command",
                                        printable(line))),
                  now);
  }
  log(5, readings_.seen_name_echo(name_, with_name));
  unit_.answering = true;

  if (!query_) {
    const auto linefeed =
        parsed.carriage_return ? EchoLinefeed::at_execution : EchoLinefeed::at_once;
    if (pins_.linefeed && *pins_.linefeed != linefeed)
      return fail(
          Reply::of(Reply::Status::garbled,
                    fmt::format("unit {}: echo '{}' has its LF {}", node_.text, printable(line),
                                linefeed == EchoLinefeed::at_execution
                                    ? "after a CR (held until execution)"
                                    : "at once") +
                        pin_hint("echo_linefeed", to_string(*pins_.linefeed))),
          now);
    log(5, readings_.seen(name_, linefeed));
    reply_ = Reply::of(Reply::Status::ok);
    // The CR LF of "execution complete" (p.12) usually follows at once; it is read here so it
    // does not spill into the next exchange.
    next_ = linefeed == EchoLinefeed::at_once ? Next::completion : Next::done;
    return next_;
  }

  if (parsed.result && late_.owed() > 0)
    // The unit holds the echo's LF back: a late result of another unit can end its line.
    return fail(Reply::of(Reply::Status::garbled,
                          fmt::format("unit {}: '{}' may end with the late answer to an earlier "
                                      "request ({} owed); not taken",
                                      node_.text, printable(line), late_.owed())),
                now);
  if (parsed.result) {
    if (pins_.placement == ResultPlacement::next_line)
      return fail(Reply::of(Reply::Status::garbled,
                            misplaced_result(node_, ResultPlacement::echo_line, line)),
                  now);
    log(5, readings_.seen(name_, ResultPlacement::echo_line));
    Reply r = Reply::of(Reply::Status::ok);
    r.values = parsed.result->values;
    return finish(std::move(r));
  }
  next_ = Next::result;
  return next_;
}

Exchange::Next Exchange::on_completion(std::string_view bytes, Clock::time_point now) {
  late_.stray(bytes, now);
  return finish(Reply::of(Reply::Status::ok));
}

Exchange::Next Exchange::on_result_failure(Reply failure, Clock::time_point now) {
  if (failure.status == Reply::Status::link_down) return finish(std::move(failure));
  late_.owe_result(now);
  if (failure.status == Reply::Status::timeout)
    failure =
        Reply::of(Reply::Status::garbled, fmt::format("unit {} echoed '{}' but sent no result line",
                                                      node_.text, printable(request_.command)));
  return fail(std::move(failure), now);
}

Exchange::Next Exchange::on_result(std::string_view line, Clock::time_point now) {
  Reply r = interpret_ims_result(node_, request_, line);
  if (r.status != Reply::Status::ok) {
    late_.owe_result(now);
    late_.stray(line, now);
    return fail(std::move(r), now);
  }
  if (late_.owed() > 0)
    // One of the results still owed may be this one: ours is owed instead.
    return fail(Reply::of(Reply::Status::garbled,
                          fmt::format("unit {}: result '{}' may be the late answer to an "
                                      "earlier request ({} owed); not taken",
                                      node_.text, printable(line), late_.owed())),
                now);
  if (pins_.placement == ResultPlacement::echo_line)
    return fail(Reply::of(Reply::Status::garbled,
                          misplaced_result(node_, ResultPlacement::next_line, line)),
                now);
  log(5, readings_.seen(name_, ResultPlacement::next_line));
  return finish(std::move(r));
}

}  // namespace fieldgate::ims
