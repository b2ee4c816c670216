#include "drivers/ims_party_line/ims_family.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <functional>
#include <variant>

#include "drivers/ims_party_line/ims_codec.hpp"

namespace fieldgate {

namespace {

// A character every 5 ms leaves the echo of each time to come back even at 9600 baud: how a
// fast chain is paced where the echo is not waited for.
constexpr std::chrono::milliseconds kPacedCharGap{5};

using Clock = std::chrono::steady_clock;

char name_of(const NodeAddress& node) {
  return static_cast<char>(node.number);
}

Reply refused(const ims::RefusalReply& refusal) {
  return Reply::of(Reply::Status::device_error, refusal.text, static_cast<int64_t>(refusal.code));
}

std::size_t one_byte(std::string_view buf) {
  return buf.empty() ? 0 : 1;
}

std::size_t everything(std::string_view buf) {
  return buf.size();
}

std::optional<Reply> failed_read(const LinkRead& read, std::string_view what, char name) {
  switch (read.status) {
    case LinkRead::Status::frame:
      return std::nullopt;
    case LinkRead::Status::timeout:
      if (read.partial.empty())
        return Reply::of(Reply::Status::timeout,
                         fmt::format("no {} from unit {}", what, ims::printable({&name, 1})));
      return Reply::of(Reply::Status::garbled,
                       fmt::format("incomplete {} '{}'", what, ims::printable(read.partial)));
    case LinkRead::Status::overflow:
      return Reply::of(Reply::Status::garbled,
                       fmt::format("{} longer than any IMS line: '{}'", what,
                                   ims::printable(read.partial.substr(0, 40))));
    case LinkRead::Status::error:
      return Reply::of(Reply::Status::link_down, read.error.message());
  }
  return std::nullopt;
}

struct LineRead {
  std::optional<Reply> failure;
  std::string line;
  std::string partial;  // of a failed read
};

asio::awaitable<LineRead> read_line(Link& link, const LinkTiming& timing, std::string_view what,
                                    char name, std::string_view prefix = {}) {
  LineRead out;
  for (int blank = 0;; ++blank) {
    LinkRead read = co_await link.read_frame(ims::line_length, timing);
    if (auto failure = failed_read(read, what, name)) {
      if (!prefix.empty() && failure->status == Reply::Status::timeout)
        failure = Reply::of(Reply::Status::garbled,
                            fmt::format("incomplete {} '{}'", what, ims::printable(prefix)));
      out.failure = failure;
      out.partial = std::string(prefix) + read.partial;
      co_return out;
    }
    out.line = std::string(prefix) + read.frame;
    if (!ims::is_blank_line(out.line) || blank == ims::kMaxBlankLines || !prefix.empty())
      co_return out;
  }
}

// Sends the line a character at a time, each once the previous one has come back (manual p.14:
// "monitor echoed data to avoid UART over-run"). The name may or may not be echoed; the echo of
// the closing LF is not waited for here (it may come at execution, after a result). The line is
// always sent whole: a unit left with half a line would take the next line as its rest, and only
// ESC, which stops every axis, clears it. Returns the echo so far, or the failure.
asio::awaitable<std::pair<std::optional<Reply>, std::string>> send_paced(Link& link,
                                                                         const NodeAddress& node,
                                                                         const Request& request,
                                                                         const LinkTiming& timing) {
  const char name = name_of(node);
  const std::string line = ims::encode_line(name, request.command);
  const std::string_view with_name(line);
  const std::string_view without_name = with_name.substr(1);
  // After a failure the rest of the line still goes out, paced by time as the proof is: back
  // to back, a unit stepping fast would overrun and could take a garbled line for another.
  const auto gap =
      std::max(std::chrono::microseconds(static_cast<int64_t>(2 * link.char_time_us()) + 1),
               std::chrono::microseconds(kPacedCharGap));
  std::optional<Reply> failure;
  std::string echoed;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (auto ec = co_await link.send(with_name.substr(i, 1)))
      co_return std::pair{Reply::of(Reply::Status::link_down, ec.message()), echoed};
    if (i == 0 || i + 1 == line.size()) continue;  // the name's echo is optional; LF: see above
    if (failure) {
      co_await link.pause(gap);
      continue;
    }
    // Complete through character i, with or without the name in front.
    const auto complete = [&] {
      return echoed == without_name.substr(0, i) || echoed == with_name.substr(0, i + 1);
    };
    const auto consistent = [&] {
      return without_name.starts_with(echoed) || with_name.starts_with(echoed);
    };
    while (!failure && !complete()) {
      const LinkRead read = co_await link.read_frame(one_byte, timing);
      if (read.status == LinkRead::Status::timeout && echoed.empty()) {
        failure = Reply::of(Reply::Status::timeout,
                            fmt::format("no echo from unit {}", ims::printable({&name, 1})));
      } else if (read.status == LinkRead::Status::timeout) {
        failure = Reply::of(Reply::Status::garbled,
                            fmt::format("paced echo stopped after '{}' of '{}'",
                                        ims::printable(echoed), ims::printable(line)));
      } else if (auto bad = failed_read(read, "echo", name)) {
        failure = bad;
      } else if (echoed.empty() && (read.frame == "\r" || read.frame == "\n")) {
        continue;  // the late CR LF of an earlier command, not part of this echo
      } else {
        echoed += read.frame;
        if (!consistent())
          failure = Reply::of(Reply::Status::garbled,
                              fmt::format("echo '{}' does not match '{}'", ims::printable(echoed),
                                          ims::printable(line)));
      }
      if (failure && failure->status == Reply::Status::link_down)
        co_return std::pair{failure, echoed};
    }
  }
  co_return std::pair{failure, echoed};
}

}  // namespace

void ImsPartyLineFamily::log(Link& link, int level, const std::optional<std::string>& text) {
  if (text) link.note(*text, level);
}

std::chrono::microseconds ImsPartyLineFamily::late_window(const LinkTiming& timing) {
  return std::max<std::chrono::microseconds>(5 * timing.reply_timeout,
                                             std::chrono::milliseconds(250));
}

std::optional<NodeAddress> ImsPartyLineFamily::parse_address(std::string_view text,
                                                             std::string& error) const {
  const auto name = ims::parse_name(text, error);
  if (!name) return std::nullopt;
  NodeAddress n;
  n.text = std::string(1, *name);
  n.number = static_cast<unsigned char>(*name);
  return n;
}

namespace {

// One reply of the proof: blank lines, the echo line, and the result line unless the result
// ended the echo's line. A line that is no echo of `command` is a frame of its own (a stray).
std::size_t proof_reply_length(std::string_view buffer, char name, std::string_view command) {
  std::size_t at = 0;
  const auto next_line = [&]() -> std::optional<std::string_view> {
    for (;;) {
      const std::size_t n = ims::line_length(buffer.substr(at));
      if (n == 0) return std::nullopt;
      const std::string_view line = buffer.substr(at, n);
      at += n;
      if (!ims::is_blank_line(line)) return line;
    }
  };
  const auto echo = next_line();
  if (!echo) return 0;
  const ims::EchoLine parsed = ims::parse_echo_line(name, command, *echo);
  if (parsed.match == ims::EchoMatch::mismatch || parsed.result) return at;
  return next_line() ? at : 0;
}

AlignmentStep query_step(const NodeAddress& node, std::string command) {
  const char name = name_of(node);
  AlignmentStep step;
  step.request = ims::encode_line(name, command);
  step.splitter = [name, command](std::string_view buffer) {
    return proof_reply_length(buffer, name, command);
  };
  step.expected = fmt::format("the echo of '{}' and its result", command);
  step.matches = [node, command](std::string_view frame) {
    const Request request{command, Request::Expect::values, NumberFormat::decimal};
    return interpret_ims_reply(node, request, frame).status == Reply::Status::ok;
  };
  return step;
}

}  // namespace

std::optional<AlignmentProof> ImsPartyLineFamily::alignment_proof(NodeContext& context,
                                                                  const LinkTiming&) {
  const NodeAddress& node = context.address();
  AlignmentProof proof;
  proof.name = fmt::format("{0}^ -> ^ and a result, {0}Z -> Z and a result", node.text);
  // Two queries with different echoes: a late reply to `^` taken for the first answer leaves
  // the real one to the second step, whose echo must be `Z`.
  proof.steps.push_back(query_step(node, "^"));
  proof.steps.push_back(query_step(node, "Z"));
  if (shadow_.fast()) {
    // A unit stepping fast overruns on back-to-back characters (manual p.14): the proof is
    // paced like every other line, by time here (its echo is part of the answer): 5 ms leaves
    // the echo of each character time to come back even at 9600 baud.
    for (auto& step : proof.steps) step.char_gap = kPacedCharGap;
  }
  return proof;
}

NodeContextPtr ImsPartyLineFamily::bind_node(const NodeAddress& node, const Model& model) {
  Diagnostics reported;  // validate_model reported them; a model with errors never runs
  const auto v = check_model_options(model, name(), model_options(), reported);
  ims::ReadingPins pins;
  ims::parse_result_placement(v.text("result_placement"), pins.placement);
  ims::parse_echo_linefeed(v.text("echo_linefeed"), pins.linefeed);
  readings_.pin(name_of(node), pins);
  shadow_.limit(name_of(node), {v.number("pacing_step_rate"), v.duration("save_interval")});
  return ProtocolFamily::bind_node(node, model);
}

asio::awaitable<void> ImsPartyLineFamily::flush(Link& link) {
  const LinkTiming no_wait{std::chrono::microseconds(0), std::chrono::microseconds(0)};
  const LinkRead read = co_await link.read_frame(everything, no_wait);
  if (read.status == LinkRead::Status::frame) late_.stray(read.frame, Clock::now());
  link.discard_input();
}

asio::awaitable<void> ImsPartyLineFamily::drain(Link& link, const LinkTiming& timing) {
  // Quiet for a reply timeout, so a reply just slower than the timeout ends here and not in the
  // next exchange. Bounded, in case a unit streams without end (Z1, a tracing program).
  const LinkTiming quiet{timing.reply_timeout, timing.byte_timeout};
  const auto deadline = Clock::now() + 4 * timing.reply_timeout + 4 * timing.byte_timeout;
  std::string drained;
  while (Clock::now() < deadline) {
    const LinkRead read = co_await link.read_frame(everything, quiet);
    if (read.status != LinkRead::Status::frame) break;
    drained += read.frame;
  }
  late_.stray(drained, Clock::now());
  link.discard_input();
}

asio::awaitable<LinkResync> ImsPartyLineFamily::resync_after_failure(Link& link,
                                                                     const LinkTiming& timing) {
  LinkResync found = co_await ProtocolFamily::resync_after_failure(link, timing);
  late_.stray(found.drained, Clock::now());
  co_return found;
}

asio::awaitable<void> ImsPartyLineFamily::on_link_open(Link& link, const LinkTiming&) {
  // No LF to "finish" a line a previous run may have left half-sent: it would execute the half.
  // Such a line garbles one exchange at most, which then resynchronises.
  link.discard_input();
  late_ = {};
  co_return;
}

asio::awaitable<Reply> ImsPartyLineFamily::transact_global(Link& link, const Request& request,
                                                           const LinkTiming& timing) {
  if (request.expect == Request::Expect::values)
    co_return Reply::of(Reply::Status::device_error,
                        "a bus-wide request cannot read: every unit's reply would collide");
  if (request.command.empty() || request.command.find_first_of("\r\n") != std::string::npos)
    co_return refused({ims::Refusal::invalid_line, "empty or multi-line global command"});
  co_await flush(link);
  if (auto ec = co_await link.send(ims::encode_global(request.command)))
    co_return Reply::of(Reply::Status::link_down, ec.message());
  // ESC and ^C get no answer in party mode; after `*` every unit echoes at once. Nothing of it
  // can be attributed, so it is thrown away.
  co_await drain(link, timing);
  shadow_.global(request.command, Clock::now());
  co_return Reply::of(Reply::Status::ok, "sent to every unit on the chain");
}

asio::awaitable<Reply> ImsPartyLineFamily::send_urgent(Link& link, const NodeAddress&,
                                                       const Request& request) {
  if (!request.bus_wide || !ims::is_global_character_command(request.command))
    co_return refused({ims::Refusal::not_global,
                       fmt::format("only ESC, ^C and @ of a bus-wide action can be sent urgently, "
                                   "not '{}'",
                                   ims::printable(request.command))});
  if (auto ec = co_await link.send(ims::encode_global(request.command)))
    co_return Reply::of(Reply::Status::link_down, ec.message());
  shadow_.global(request.command, Clock::now());
  co_return Reply::of(Reply::Status::ok, "sent to every unit on the chain");
}

// GCC 12 at -O2 inlines Asio's aligned coroutine-frame allocation into large coroutines and then
// flags the frame's own sized delete as a mismatch (a false positive;
// gateway/register_map/action_runner.cpp trips it too).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
asio::awaitable<Reply> ImsPartyLineFamily::transact(Link& link, const NodeAddress& node,
                                                    const Request& request,
                                                    const LinkTiming& timing) {
  if (request.bus_wide) co_return co_await transact_global(link, request, timing);
  const char name = name_of(node);
  if (ims::classify(request.command) == ims::CommandClass::index && shadow_.jogging(name)) {
    Reply stopped = co_await end_jog(link, node, request, timing);
    if (stopped.status != Reply::Status::ok) co_return stopped;
  }
  if (auto refusal = shadow_.check(name, request.command, Clock::now()))
    co_return refused(*refusal);

  LinkTiming t = timing;
  const bool paced = shadow_.fast();
  // Serial handling slows while a unit steps fast (manual p.14); digest §9 doubles the timeout.
  if (paced) t.reply_timeout *= 2;
  co_await flush(link);
  log(link, 5, late_.expire(Clock::now(), late_window(t)));

  if (ims::classify(request.command) == ims::CommandClass::no_echo) {
    // P, Q, q and X do not echo in party mode (§2); X answers a garbled '"32.'. Nothing to
    // verify: whatever comes back is thrown away.
    if (auto ec = co_await link.send(ims::encode_line(name, request.command)))
      co_return Reply::of(Reply::Status::link_down, ec.message());
    co_await drain(link, t);
    if (request.expect == Request::Expect::values)
      co_return Reply::of(Reply::Status::garbled,
                          fmt::format("'{}' gives no readable reply in party mode",
                                      ims::printable(request.command)));
    co_return Reply::of(Reply::Status::ok, "sent; no echo in party mode");
  }

  Reply reply = co_await exchange(link, node, request, t, paced);
  if (reply.status == Reply::Status::ok) {
    shadow_.acknowledged(
        name, request.command, Clock::now(),
        reply.values.empty() ? std::nullopt : std::optional<int64_t>(reply.values.front()));
  }
  co_return reply;
}

std::optional<std::string> ImsPartyLineFamily::pipelined_request(NodeContext& node,
                                                                 const Request& request) {
  // What transact() does before its line goes out, where none of it needs the line: no pacing,
  // no jog to end first, nothing the shadow refuses, an echo to read.
  if (request.bus_wide || shadow_.fast()) return std::nullopt;
  const char name = name_of(node.address());
  const auto kind = ims::classify(request.command);
  if (kind == ims::CommandClass::no_echo ||
      (kind == ims::CommandClass::index && shadow_.jogging(name)) ||
      shadow_.check(name, request.command, Clock::now()))
    return std::nullopt;
  return ims::encode_line(name, request.command);
}

// A move aborts a jog (docs/axis-profile.md, buffer mode Aborting): an index sent to a jogging
// unit would wait behind the jog's ramp and answer nothing until it starts (p.13), so the jog is
// ramped down with M0 first and `^` read until the unit is idle; then the index goes out.
asio::awaitable<Reply> ImsPartyLineFamily::end_jog(Link& link, const NodeAddress& node,
                                                   const Request& request,
                                                   const LinkTiming& timing) {
  const char name = name_of(node);
  const Request ramp_down{"M0", Request::Expect::ack, NumberFormat::decimal};
  Reply r = co_await transact(link, node, ramp_down, timing);
  const auto deadline = Clock::now() + kJogRampDownPatience;
  const Request status{"^", Request::Expect::values, NumberFormat::decimal};
  while (r.status == Reply::Status::ok && shadow_.moving(name)) {
    if (Clock::now() >= deadline) {
      co_return refused(
          {ims::Refusal::axis_moving,
           fmt::format("unit {}: the jog did not come to rest within {} s of M0; "
                       "'{}' not sent",
                       name, kJogRampDownPatience.count(), ims::printable(request.command))});
    }
    co_await link.pause(kJogPollInterval);
    r = co_await transact(link, node, status, timing);
  }
  if (r.status != Reply::Status::ok) {
    r.text = fmt::format("ending the jog before '{}': {}", ims::printable(request.command),
                         r.text.empty() ? std::string(to_string(r.status)) : r.text);
    co_return r;
  }
  log(link, 6,
      fmt::format("unit {}: jog ramped down (M0) before '{}'", name,
                  ims::printable(request.command)));
  co_return r;
}

asio::awaitable<Reply> ImsPartyLineFamily::exchange(Link& link, const NodeAddress& node,
                                                    const Request& request, const LinkTiming& t,
                                                    bool paced) {
  const char name = name_of(node);
  ims::Exchange x(node, request, readings_, late_, units_[name], late_window(t));
  // After the echoed command a unit may pause to execute before the rest of the line (a result
  // on the echo's line, or the held LF), so the gap may run to the reply timeout.
  const LinkTiming echo_timing{t.reply_timeout, std::max(t.byte_timeout, t.reply_timeout)};
  std::string echoed;
  if (paced) {
    auto [failure, so_far] = co_await send_paced(link, node, request, t);
    if (failure) x.on_send_failure(*failure, so_far, Clock::now());
    echoed = std::move(so_far);
  } else if (auto ec = co_await link.send(ims::encode_line(name, request.command))) {
    x.on_link_down(ec.message());
  }
  if (x.next() == ims::Exchange::Next::echo) {
    const LineRead echo = co_await read_line(link, echo_timing, "echo", name, echoed);
    if (echo.failure)
      x.on_echo_failure(*echo.failure, echo.partial, Clock::now());
    else
      x.on_echo(echo.line, Clock::now());
  }
  if (x.next() == ims::Exchange::Next::completion) {
    const LinkTiming completion{t.byte_timeout, t.byte_timeout};
    const LinkRead done = co_await link.read_frame(ims::line_length, completion);
    if (done.status == LinkRead::Status::error)
      x.on_link_down(done.error.message());
    else
      x.on_completion(done.status == LinkRead::Status::frame ? done.frame : "", Clock::now());
  }
  if (x.next() == ims::Exchange::Next::result) {
    const LineRead result = co_await read_line(link, t, "result line", name);
    if (result.failure)
      x.on_result_failure(*result.failure, Clock::now());
    else
      x.on_result(result.line, Clock::now());
  }
  for (auto& line : x.take_log()) log(link, line.level, std::move(line.text));
  if (x.reply().status == Reply::Status::garbled) co_await drain(link, t);
  co_return x.reply();
}
#pragma GCC diagnostic pop

std::size_t ImsPartyLineFamily::estimate_wire_chars(const NodeAddress& node,
                                                    const Request& request) const {
  if (request.bus_wide) return ims::encode_global(request.command).size();
  const std::size_t line = ims::encode_line(name_of(node), request.command).size();
  // The echo (name included, the longer case), then "   1000\r\n" or a bare CR LF.
  return 2 * line + (ims::expects_result(request) ? 10 : 2);
}

// --- model validation -----------------------------------------------------------------------

namespace {

struct ModelOptions {
  double firmware = 1.09;  // the older manual's firmware: no `*` global address
  std::size_t line_limit = ims::kLineLimit;
  bool line_limit_counts_name = false;
  bool addressed_soft_stop = false;
};

const ModelOptionSpecs& ims_model_options() {
  static const ModelOptionSpecs specs{
      number_option("firmware", "1.09", 0.01, 99,
                    "the indexers' firmware version; 1.15 and later know the `*` global address"),
      integer_option("line_limit", std::to_string(ims::kLineLimit), 2, 64,
                     "the longest command line a unit accepts (the manual says 12)"),
      flag_option("line_limit_counts_name", "false", "the unit name counts towards line_limit"),
      flag_option("addressed_soft_stop", "false",
                  "the units stop on an addressed soft stop (else actions may use only the "
                  "global one)"),
      choice_option("result_placement", "auto", {"auto", "next_line", "echo_line"},
                    "where a query's result comes: detected per unit (auto), on a line of its "
                    "own, or on the echo's line"),
      choice_option("echo_linefeed", "auto", {"auto", "at_once", "at_execution"},
                    "when a non-query's echoed LF comes: detected per unit (auto), at once, or "
                    "when the command has run"),
      number_option("pacing_step_rate", "10000", 1, 1e6,
                    "steps/s above which the unit's serial handling slows (manual p.14): while "
                    "a unit may step faster, every line on the chain is paced by its echo and "
                    "the reply timeout doubles"),
      duration_option("save_interval", "60s", std::chrono::seconds(0), std::chrono::hours(24 * 7),
                      "the least time between two `S` (save to EEPROM, ~400,000 write cycles) "
                      "to the unit; an earlier `S` is refused with code 3"),
  };
  return specs;
}

ModelOptions read_options(const Model& model, Diagnostics& diagnostics) {
  const auto v = check_model_options(model, "ims-party-line", ims_model_options(), diagnostics);
  ModelOptions o;
  o.firmware = v.number("firmware");
  o.line_limit = static_cast<std::size_t>(v.integer("line_limit"));
  o.line_limit_counts_name = v.flag("line_limit_counts_name");
  o.addressed_soft_stop = v.flag("addressed_soft_stop");
  return o;
}

enum class Use { read, write, action, bus_wide_action };

using RangeOf = std::function<std::pair<int64_t, int64_t>(std::string_view)>;

std::string render_extreme(const CommandTemplate& t, const RangeOf& range_of, int which) {
  return t.render([&](std::string_view name) -> int64_t {
    const auto [lo, hi] = range_of(name);
    if (which < 0) return lo;
    if (which > 0) return hi;
    return std::to_string(lo).size() >= std::to_string(hi).size() ? lo : hi;
  });
}

void check_command(const CommandTemplate& t, const RangeOf& range_of, Use use,
                   const ModelOptions& options, const SourceMark& mark, const std::string& what,
                   Diagnostics& diagnostics) {
  const std::string& s = t.source();
  const auto error = [&](const std::string& message) {
    diagnostics.error(mark, fmt::format("{}: {}", what, message));
  };
  if (s.empty()) return error("empty command");
  if (s.find_first_of("\r\n") != std::string::npos)
    return error(
        fmt::format("'{}': the family ends every line with LF itself; a CR on a party "
                    "line breaks the framing (digest §8.1)",
                    ims::printable(s)));
  if (s.find(":x}") != std::string::npos || s.find(":X}") != std::string::npos)
    return error(fmt::format("'{}': IMS data fields are decimal", s));
  if (s.front() == ims::kGlobalAddress)
    return error(
        fmt::format("'{}': the family adds the global address '*' to bus_wide actions "
                    "itself; write the plain command",
                    s));
  if (s.find(ims::kEscape) != std::string::npos || s.find(ims::kControlC) != std::string::npos) {
    const bool escape = s.find(ims::kEscape) != std::string::npos;
    if (s.size() != 1)
      return error(fmt::format("'{}': {} is sent on its own, not inside a line", ims::printable(s),
                               escape ? "ESC" : "^C"));
    if (use != Use::bus_wide_action)
      return error(
          fmt::format("{} every axis on the chain (digest §2): only an action with "
                      "bus_wide: true may send it",
                      escape ? "ESC hard-stops" : "^C resets"));
    return;
  }
  if (s.front() == ims::kSoftStop) {
    if (use == Use::bus_wide_action) {
      if (!ims::is_global_character_command(s))
        error(fmt::format("'{}': the global soft stop is '@', '@0' or '@1'", s));
      return;
    }
    if (use == Use::action && options.addressed_soft_stop) return;
    return error(
        fmt::format("'{}': '@' is typed Global (digest §2, §10.2) and may stop every "
                    "axis on the chain: send it from an action with bus_wide: true, or "
                    "set options: {{addressed_soft_stop: true}} for units known to stop "
                    "only the named axis",
                    s));
  }

  const ims::CommandClass kind = ims::classify(s);
  const char c = s.front();
  switch (kind) {
    case ims::CommandClass::unknown:
      return error(fmt::format("'{}' does not start with an IMS command character", s));
    case ims::CommandClass::wait:
      return error(
          fmt::format("'{}': W holds the echo until the motion ends and stalls the "
                      "chain (digest §8.14); use a done condition on the status point",
                      s));
    case ims::CommandClass::no_echo:
      if (c == 'P')
        return error(
            "P enters program mode, with no echo in party mode, and stores every "
            "following line as program: enter programs in Single mode on the bench");
      if (c == 'Q') return error("Q does not function in party mode");
      if (c == 'q') return error("q lists the program with no echo in party mode");
      return error(
          "X returns only '\"32.' in party mode: read the saved parameters with '[' "
          "or keep them as setpoints");
    case ims::CommandClass::program:
      return error(fmt::format("'{}' is a program instruction, not a host command", s));
    default:
      break;
  }
  if (c == '\\')
    return error(
        "'\\' writes raw EEPROM bytes and may start an over-write (digest §3): change "
        "parameters with their commands, then save with S");
  if (c == 'C' && kind == ims::CommandClass::eeprom)
    return error(
        fmt::format("'{}' erases EEPROM pages or restores factory defaults; that is "
                    "commissioning work, not a gateway action (digest §5)",
                    s));

  const std::string low = render_extreme(t, range_of, -1);
  const std::string high = render_extreme(t, range_of, 1);
  for (const auto& rendered : {low, high}) {
    const std::string line = ims::normalize_command(rendered);
    if (!ims::parse_data(std::string_view(line).substr(1)))
      return error(
          fmt::format("'{}' renders to '{}', which is not a command character with "
                      "up to two numbers (digest §1)",
                      s, line));
  }
  const auto data = ims::parse_data(std::string_view(ims::normalize_command(high)).substr(1));
  const auto field = [&](std::size_t i) -> std::optional<double> {
    if (!data || data->fields.size() <= i) return std::nullopt;
    return data->fields[i];
  };
  if ((c == 'Z' || c == 'z') && field(0).value_or(0) != 0)
    return error(
        fmt::format("'{}': continuous position output sends lines nobody asked for and "
                    "corrupts the chain (digest §8.8)",
                    s));
  if (c == 'G' && field(1).value_or(0) != 0)
    return error(fmt::format("'{}': trace output corrupts the chain (digest §8.8)", s));

  const std::size_t limit =
      options.line_limit - (options.line_limit_counts_name && options.line_limit > 1 ? 1 : 0);
  const std::string longest = ims::normalize_command(render_extreme(t, range_of, 0));
  if (longest.size() > limit)
    return error(
        fmt::format("'{}' can render to {} characters ('{}'); a unit takes at most {} "
                    "(digest §1, options line_limit{}): narrow the placeholder's "
                    "min/max or drop optional spaces",
                    s, longest.size(), longest, limit,
                    options.line_limit_counts_name ? ", the name counts" : ""));

  switch (use) {
    case Use::read:
      if (kind != ims::CommandClass::query)
        return error(
            fmt::format("'{}' returns no value in party mode (only Z, z, ^, ], A129 and "
                        "[ do; parameters have no readback, digest §4): keep written "
                        "values as setpoints",
                        s));
      if (c == '[' && field(1).value_or(1) > 10)
        return error(
            fmt::format("'{}': more than 10 bytes come back on several lines; read at "
                        "most 10 per point",
                        s));
      return;
    case Use::write:
      if (kind == ims::CommandClass::query)
        return error(fmt::format("'{}' is a query, not a write", s));
      if (kind == ims::CommandClass::eeprom)
        return error(
            fmt::format("'{}' writes the EEPROM (about 400,000 cycles): saving is an "
                        "action a user triggers, never a point write (digest §5)",
                        s));
      if (kind != ims::CommandClass::parameter)
        return error(
            fmt::format("'{}' starts motion: put it in an action with a done condition", s));
      return;
    case Use::action:
      return;
    case Use::bus_wide_action:
      if (kind == ims::CommandClass::query)
        return error(
            fmt::format("'{}': every axis would answer at once; a bus-wide action "
                        "cannot read",
                        s));
      if (kind == ims::CommandClass::eeprom)
        return error(fmt::format("'{}': save each axis on its own, deliberately", s));
      if (options.firmware < 1.15)
        return error(
            fmt::format("'{}' goes out as '*{}'; the global address '*' needs indexer "
                        "firmware 1.15 or later (set options: {{firmware: \"1.15\"}} "
                        "if the units have it)",
                        s, s));
      return;
  }
}

}  // namespace

const ModelOptionSpecs& ImsPartyLineFamily::model_options() const {
  return ims_model_options();
}

void ImsPartyLineFamily::validate_model(const Model& model, Diagnostics& diagnostics) const {
  const ModelOptions options = read_options(model, diagnostics);
  for (const auto& p : model.points) {
    const auto value_range = [&](std::string_view) {
      return std::pair{p.min.value_or(min_value(p.type)), p.max.value_or(max_value(p.type))};
    };
    if (p.read) {
      const std::string what = "point " + p.name + " read";
      if (p.read->object)
        diagnostics.error(p.mark, what + ": objects are for the canopen family");
      else if (p.read->format != NumberFormat::decimal)
        diagnostics.error(p.mark, what + ": IMS units answer in decimal");
      else
        check_command(p.read->request, value_range, Use::read, options, p.mark, what, diagnostics);
      if (p.read->field != 0 &&
          (p.read->request.source().empty() || p.read->request.source().front() != '['))
        diagnostics.error(p.mark, what + ": only '[' returns more than one value");
    }
    if (p.write) {
      const std::string what = "point " + p.name + " write";
      if (p.write->object)
        diagnostics.error(p.mark, what + ": objects are for the canopen family");
      else
        check_command(p.write->request, value_range, Use::write, options, p.mark, what,
                      diagnostics);
    }
  }
  const RangeOf setpoint_range = [&](std::string_view name) -> std::pair<int64_t, int64_t> {
    const SetpointDef* s = model.find_setpoint(std::string(name));
    if (!s) return {0, 0};
    return {s->min.value_or(min_value(s->type)), s->max.value_or(max_value(s->type))};
  };
  for (const auto& a : model.actions) {
    for (const auto& step : a.steps) {
      if (step.kind != ActionStep::Kind::send) continue;
      const std::string what = "action " + a.name;
      check_command(step.command, setpoint_range, a.bus_wide ? Use::bus_wide_action : Use::action,
                    options, step.mark, what, diagnostics);
      if (step.urgent && !(a.bus_wide && ims::is_global_character_command(step.command.source())))
        diagnostics.error(step.mark,
                          fmt::format("{}: only ESC, ^C or @ of a bus_wide action can be sent "
                                      "urgently",
                                      what));
    }
  }
}

}  // namespace fieldgate

namespace fieldgate {
FamilyPtr make_ims_party_line_family() {
  return std::make_shared<ImsPartyLineFamily>();
}
}  // namespace fieldgate
