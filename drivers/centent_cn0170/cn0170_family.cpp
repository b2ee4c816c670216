#include "drivers/centent_cn0170/cn0170_family.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <mutex>
#include <utility>

#include "drivers/printable_bytes.hpp"

namespace fieldgate {

using cn0170::Message;
using cn0170::MessageKind;

namespace {

// Lines one exchange may read before giving up (unsolicited chatter must not hold the bus).
constexpr int kMaxLinesPerExchange = 64;

const FrameSplitter kLineSplitter = cn0170::frame_length;

// Whether a field of a read is written in hex on the wire; nullopt for the status and motion
// words the family computes from position replies.
std::optional<bool> field_is_hex(const std::vector<cn0170::Query>& queries, int field) {
  for (const auto& q : queries) {
    if (field < q.value_count) {
      if (q.kind == MessageKind::position && field == 1) return std::nullopt;
      return q.hex;
    }
    field -= q.value_count;
  }
  return std::nullopt;
}

std::string join(const std::vector<int>& units) {
  std::string out;
  for (int u : units) out += (out.empty() ? "" : ", ") + std::to_string(u);
  return out;
}

}  // namespace

std::optional<NodeAddress> CententFamily::parse_address(std::string_view text,
                                                        std::string& error) const {
  const auto unit = cn0170::parse_unit_address(text, error);
  if (!unit) return std::nullopt;
  return NodeAddress::numbered(*unit);
}

std::vector<int> CententFamily::configured_units() const {
  return {configured_.begin(), configured_.end()};
}

void CententFamily::validate_model(const Model& model, Diagnostics& diagnostics) const {
  (void)cn0170::parse_options(model, diagnostics);

  const auto check_command = [&](const CommandTemplate& t, const SourceMark& mark,
                                 const std::string& what, bool in_action, bool bus_wide) {
    const std::string& s = t.source();
    if (s.empty()) return;
    if (s.find_first_of("\r\n") != std::string::npos) {
      diagnostics.error(mark,
                        fmt::format("{}: the family adds the CR; remove it from '{}'", what, s));
      return;
    }
    // Placeholders become 1, a value every numeric field accepts, to classify the instructions.
    const std::string rendered = t.render([](std::string_view) { return int64_t{1}; });
    for (const auto& instruction : cn0170::split_instructions(rendered)) {
      switch (cn0170::classify_instruction(instruction)) {
        case cn0170::InstructionKind::unit_command:
          diagnostics.error(mark, fmt::format("{}: '{}': the family selects units itself (.Un "
                                              "before the first request for a unit)",
                                              what, instruction));
          break;
        case cn0170::InstructionKind::unit_assignment:
          if (!in_action)
            diagnostics.error(mark, fmt::format("{}: unit assignment '{}' belongs in an action",
                                                what, instruction));
          break;
        case cn0170::InstructionKind::mode_program:
          diagnostics.error(mark, fmt::format("{}: M2 from Immediate Mode erases the stored "
                                              "program (manual p.7); the gateway never sends it",
                                              what));
          break;
        case cn0170::InstructionKind::kill:
          if (!bus_wide)
            diagnostics.error(mark, fmt::format("{}: K is relayed down the whole chain (p.13): "
                                                "put it in an action with bus_wide: true",
                                                what));
          break;
        default:
          if (bus_wide)
            diagnostics.error(mark, fmt::format("{}: a bus-wide CN0170 action may only send K, "
                                                "the one instruction relayed down the chain; "
                                                "found '{}'",
                                                what, instruction));
          break;
      }
    }
  };

  for (const auto& p : model.points) {
    if (p.read) {
      const std::string where = "point " + p.name + " read";
      const std::string& src = p.read->request.source();
      if (p.read->object)
        diagnostics.error(p.mark, fmt::format("{}: objects are for the canopen family", where));
      if (p.read->format == NumberFormat::hex24)
        diagnostics.error(p.mark, fmt::format("{}: the CN0170 has no 24-bit hex replies", where));
      if (!src.empty() && src.front() == '@') {
        if (src != cn0170::kCountersRequest)
          diagnostics.error(p.mark, fmt::format("{}: unknown gateway-local read '{}' (the family "
                                                "knows {})",
                                                where, src, cn0170::kCountersRequest));
        else if (p.read->field >= cn0170::kCounterFields)
          diagnostics.error(p.mark, fmt::format("{}: {} has fields 0..{}", where, src,
                                                cn0170::kCounterFields - 1));
        if (p.read->format != NumberFormat::decimal)
          diagnostics.error(p.mark, fmt::format("{}: {} values are plain numbers; remove the "
                                                "format",
                                                where, src));
      } else if (!src.empty()) {
        if (src.find_first_of("\r\n") != std::string::npos)
          diagnostics.error(p.mark, fmt::format("{}: the family adds the CR", where));
        std::vector<cn0170::Query> queries;
        bool known = true;
        for (const auto& part : cn0170::split_instructions(src)) {
          auto q = cn0170::classify_query(part);
          if (!q) {
            diagnostics.error(p.mark, fmt::format("{}: '{}' is not a CN0170 query the family "
                                                  "can match to its reply (digest §5)",
                                                  where, part));
            known = false;
            continue;
          }
          queries.push_back(*q);
        }
        if (known && !queries.empty()) {
          const int values = cn0170::values_of_request(queries);
          if (p.read->field >= values) {
            diagnostics.error(p.mark, fmt::format("{}: '{}' yields fields 0..{}, not {}", where,
                                                  src, values - 1, p.read->field));
          } else if (const auto hex = field_is_hex(queries, p.read->field)) {
            // The motion word and a position's status word are the family's own numbers.
            if (*hex && p.read->format != NumberFormat::hex)
              diagnostics.error(p.mark, fmt::format("{}: field {} of '{}' is a hex reply "
                                                    "(lower-case h suffix): add format: hex",
                                                    where, p.read->field, src));
            else if (!*hex && p.read->format == NumberFormat::hex)
              diagnostics.error(p.mark, fmt::format("{}: field {} of '{}' is not a hex reply; "
                                                    "remove format: hex",
                                                    where, p.read->field, src));
          }
        }
      }
    }
    if (p.write)
      check_command(p.write->request, p.mark, "point " + p.name + " write", false, false);
  }
  for (const auto& a : model.actions) {
    const std::string what = "action " + a.name;
    for (const auto& s : a.steps) {
      if (s.kind != ActionStep::Kind::send) continue;
      check_command(s.command, s.mark, what, true, a.bus_wide);
      if (s.urgent)
        diagnostics.error(s.mark, fmt::format("{}: the CN0170 has no urgent commands (the line is "
                                              "never held; K and Q are ordinary commands)",
                                              what));
    }
  }
}

NodeContextPtr CententFamily::bind_node(const NodeAddress& node, const Model& model) {
  configured_.insert(node.number);
  // Options apply to the whole chain: its first node's model sets them. Errors were reported by
  // validate_model.
  if (!options_bound_) {
    Diagnostics reported;
    options_ = cn0170::parse_options(model, reported);
    options_bound_ = true;
  }
  return ProtocolFamily::bind_node(node, model);
}

void CententFamily::flush_log(Link& link) {
  for (const auto& e : chain_.events)
    link.note(fmt::format("centent-cn0170 chain: {}", e.text), e.level);
  chain_.events.clear();
}

asio::awaitable<std::optional<std::vector<int>>> CententFamily::ask_units(Link& link,
                                                                          const LinkTiming& timing,
                                                                          std::string_view query,
                                                                          MessageKind answer) {
  if (co_await link.send(query)) co_return std::nullopt;
  std::vector<int> units;
  for (int i = 0; i < kMaxLinesPerExchange; ++i) {
    const LinkRead read = co_await link.read_frame(kLineSplitter, timing);
    if (read.status != LinkRead::Status::frame) break;
    const Message m = cn0170::parse_message(read.frame);
    if (m.kind == answer)
      units.push_back(m.subject);
    else
      chain_.absorb(m);
  }
  co_return units;
}

asio::awaitable<void> CententFamily::on_link_open(Link& link, const LinkTiming& timing) {
  chain_.link_opened();
  link.discard_input();
  if (options_.autobaud_cr) {
    // After a power-up every unit waits for a CR to measure the baud rate and answers U<n>;
    // units already running read it as an empty line.
    const auto answered = co_await ask_units(link, timing, "\r", MessageKind::autobaud);
    if (answered && !answered->empty())
      chain_.log(5, fmt::format("auto-baud CR answered by unit(s) {}", join(*answered)));
  }
  if (options_.discover_chain) {
    if (const auto answered = co_await ask_units(link, timing, ".U?\r", MessageKind::unit_list)) {
      const std::vector<int>& order = *answered;
      chain_.order = order;
      chain_.order_known = !order.empty();
      if (order.empty()) {
        chain_.log(4,
                   "no unit answered .U? (chain unpowered, not auto-bauded, or in Program "
                   "Mode)");
      } else {
        chain_.log(5, fmt::format("chain order from .U?: {}", join(order)));
        for (int u : configured_)
          if (std::find(order.begin(), order.end(), u) == order.end())
            chain_.log(4, fmt::format("unit {} is configured but did not answer .U? (missing, "
                                      "unpowered, numbered differently or in Program Mode)",
                                      u));
        std::set<int> reported;
        for (int u : order) {
          if (!reported.insert(u).second) continue;
          const auto n = std::count(order.begin(), order.end(), u);
          if (n > 1)
            chain_.log(4, fmt::format("unit {} answered .U? {} times: duplicate unit numbers; "
                                      "the one nearest the host traps everything sent to {}",
                                      u, n, u));
          if (!configured_.count(u))
            chain_.log(4, fmt::format("unit {} is on the chain but not configured", u));
        }
      }
    }
  }
  flush_log(link);
}

asio::awaitable<Reply> CententFamily::run(Link& link, int unit, cn0170::Plan plan, std::string what,
                                          const LinkTiming& timing) {
  if (plan.refused) co_return *plan.refused;
  chain_.expire_owed(std::chrono::steady_clock::now(),
                     std::max<std::chrono::steady_clock::duration>(5 * timing.reply_timeout,
                                                                   std::chrono::milliseconds(250)));
  if (chain_.drain_before_next) {
    // What arrived since is read, not just dropped: late replies among it pay their debts.
    const LinkTiming no_wait{std::chrono::microseconds(0), std::chrono::microseconds(0)};
    for (int i = 0; i < kMaxLinesPerExchange; ++i) {
      const LinkRead read = co_await link.read_frame(kLineSplitter, no_wait);
      if (read.status != LinkRead::Status::frame) break;
      const cn0170::Message m = cn0170::parse_message(read.frame);
      if (m.kind != cn0170::MessageKind::blank) chain_.absorb(m);
    }
    link.discard_input();
    chain_.drain_before_next = false;
  }
  const std::error_code ec = co_await link.send(plan.bytes);
  if (ec) {
    chain_.forget_selection();
    co_return Reply::of(Reply::Status::link_down, ec.message());
  }
  if (plan.expected.empty()) co_return Reply::of(Reply::Status::ok);
  co_return co_await read_replies(
      link, cn0170::Exchange(chain_, unit, std::move(plan), std::move(what)), timing);
}

asio::awaitable<LinkResync> CententFamily::resync_after_failure(Link& link,
                                                                const LinkTiming& timing) {
  LinkResync found = co_await ProtocolFamily::resync_after_failure(link, timing);
  std::string_view rest = found.drained;
  while (const std::size_t n = cn0170::frame_length(rest)) {
    const cn0170::Message m = cn0170::parse_message(rest.substr(0, n));
    if (m.kind != cn0170::MessageKind::blank) chain_.absorb(m);
    rest.remove_prefix(n);
  }
  flush_log(link);
  co_return found;
}

asio::awaitable<Reply> CententFamily::read_replies(Link& link, cn0170::Exchange exchange,
                                                   const LinkTiming& timing) {
  for (int i = 0; i < kMaxLinesPerExchange; ++i) {
    const LinkRead read = co_await link.read_frame(kLineSplitter, timing);
    if (read.status == LinkRead::Status::frame) {
      if (exchange.on_line(read.frame)) {
        const auto instead = co_await take_line_end(link, read.frame, timing);
        chain_.owe(exchange.unit(), exchange.owes(),
                   exchange.paid_debt_since().value_or(std::chrono::steady_clock::now()));
        if (instead)
          co_return Reply::of(
              Reply::Status::garbled,
              fmt::format("'{}' where the LF of a CR LF was due", printable_bytes(*instead)));
        co_return exchange.reply();
      }
      continue;
    }
    if (read.status == LinkRead::Status::timeout) {
      exchange.on_timeout(read.partial);
    } else if (read.status == LinkRead::Status::overflow) {
      exchange.on_overflow(read.partial);
    } else {
      exchange.on_link_error(read.error.message());
    }
    chain_.owe(exchange.unit(), exchange.owes(),
               exchange.paid_debt_since().value_or(std::chrono::steady_clock::now()));
    co_return exchange.reply();
  }
  if (!exchange.finished()) exchange.on_too_many_lines();
  chain_.owe(exchange.unit(), exchange.owes(),
             exchange.paid_debt_since().value_or(std::chrono::steady_clock::now()));
  co_return exchange.reply();
}

asio::awaitable<std::optional<std::string>> CententFamily::take_line_end(
    Link& link, std::string_view last_frame, const LinkTiming& timing) {
  if (last_frame.empty() || last_frame.back() != '\r') co_return std::nullopt;
  const FrameSplitter one_byte = [](std::string_view buffer) -> std::size_t {
    return buffer.empty() ? 0 : 1;
  };
  if (link.buffered() > 0) {
    if (link.buffered_bytes().front() != '\n') co_return std::nullopt;  // the bus sees it
    const LinkTiming no_wait{std::chrono::microseconds(0), std::chrono::microseconds(0)};
    co_await link.read_frame(one_byte, no_wait);
    crlf_line_ends_ = true;
    co_return std::nullopt;
  }
  // A CR-only chain is not kept waiting: its next line may lead with a blank one.
  if (!crlf_line_ends_) co_return std::nullopt;
  const LinkTiming gap{timing.byte_timeout, timing.byte_timeout};
  const LinkRead read = co_await link.read_frame(one_byte, gap);
  if (read.status != LinkRead::Status::frame || read.frame == "\n") co_return std::nullopt;
  co_return read.frame;
}

namespace {

// One reply line of the proof: blank lines before it (the LF of a CR LF) and the LF after its CR
// are part of it, so nothing of an answered step is left behind.
std::size_t proof_line_length(std::string_view buffer) {
  const auto begin = buffer.find_first_not_of("\r\n");
  if (begin == std::string_view::npos) return 0;
  const auto end = buffer.find_first_of("\r\n", begin);
  if (end == std::string_view::npos) return 0;
  return buffer[end] == '\r' && end + 1 < buffer.size() && buffer[end + 1] == '\n' ? end + 2
                                                                                   : end + 1;
}

AlignmentStep rejected_string_step(std::string request, int unit, std::string rejected) {
  AlignmentStep step;
  step.request = std::move(request);
  step.splitter = proof_line_length;
  step.expected = fmt::format("'{}\"{}\" ?'", unit == 0 ? "" : std::to_string(unit), rejected);
  step.matches = [unit, rejected](std::string_view frame) {
    const cn0170::Message m = cn0170::parse_message(frame);
    return m.kind == cn0170::MessageKind::reject && m.unit == unit && m.text == rejected;
  };
  return step;
}

}  // namespace

std::optional<AlignmentProof> CententFamily::alignment_proof(NodeContext& node, const LinkTiming&) {
  const int unit = node.address().number;
  // The proof selects the unit on its own: the chain's selection is unknown after it, whatever
  // happens.
  chain_.forget_selection();
  chain_.drain_before_next = true;
  AlignmentProof proof;
  proof.name = fmt::format("XY? -> '{0}\"XY?\" ?', YX? -> '{0}\"YX?\" ?'",
                           unit == 0 ? "" : std::to_string(unit));
  // XY? is the manual's own example of a rejected string (p.3); YX? is no instruction either.
  // The leading CR lets a unit that reset take its auto-baud (its U<n> is drained).
  std::string first = options_.leading_cr ? "\r" : "";
  first += cn0170::encode_select(unit) + "XY?\r";
  proof.steps.push_back(rejected_string_step(std::move(first), unit, "XY?"));
  proof.steps.push_back(rejected_string_step("YX?\r", unit, "YX?"));
  return proof;
}

asio::awaitable<std::optional<Reply>> CententFamily::set_up(Link& link, int unit,
                                                            const LinkTiming& timing) {
  auto& state = chain_.units[static_cast<std::size_t>(unit)];
  const bool recheck_mode = options_.guard_program_mode && (state.mode == 2 || state.mode == 3);
  if (state.set_up && !recheck_mode) co_return std::nullopt;
  const Request mode_query{"M?", Request::Expect::values, NumberFormat::decimal};
  Reply mode = co_await run(link, unit, cn0170::plan_request(chain_, options_, unit, mode_query),
                            "M?", timing);
  if (mode.status != Reply::Status::ok) co_return mode;
  if (state.set_up) co_return std::nullopt;
  if (state.mode == 3) {
    // Power-up resumes the last mode (digest §3, §6 #3). The gateway runs its units in Immediate
    // Mode: in M3 a unit may discard what the host sends, and its M3 would confirm commands that
    // never ran. A program the unit runs on its own is left to it only while the gateway has not
    // contacted it; run_program (M3;G) puts it back in M3 on purpose, and then motor commands
    // are refused until immediate_mode.
    const Request immediate{"M1", Request::Expect::ack, NumberFormat::decimal};
    Reply r = co_await run(link, unit, cn0170::plan_request(chain_, options_, unit, immediate),
                           "M1", timing);
    if (r.status != Reply::Status::ok) {
      chain_.log(4, fmt::format("unit {} is in Operate Mode (M3) and did not confirm M1: {}", unit,
                                r.text));
      co_return r;
    }
    chain_.log(5, fmt::format("unit {} was in Operate Mode (M3) at first contact, where it may "
                              "discard the host's instructions: switched to Immediate Mode (M1)",
                              unit));
  }
  if (state.mode == 1 && options_.overflow != cn0170::Options::Overflow::leave) {
    const bool rts = options_.overflow == cn0170::Options::Overflow::rts;
    std::string command = options_.overflow_command;
    if (command.empty()) command = rts ? "M1\\+" : "M1\\-";
    const Request set{command, Request::Expect::ack, NumberFormat::decimal};
    Reply r = co_await run(link, unit, cn0170::plan_request(chain_, options_, unit, set), command,
                           timing);
    if (r.status == Reply::Status::device_error && r.device_code == cn0170::kRejected &&
        options_.overflow_command.empty()) {
      // The manual prints both M1\- and M1- (§9 #11).
      command = rts ? "M1+" : "M1-";
      const Request plain{command, Request::Expect::ack, NumberFormat::decimal};
      r = co_await run(link, unit, cn0170::plan_request(chain_, options_, unit, plain), command,
                       timing);
    }
    if (r.status == Reply::Status::ok) {
      chain_.log(6, fmt::format("unit {}: overflow {} mode set ({})", unit, rts ? "RTS" : "warning",
                                command));
    } else if (r.status == Reply::Status::device_error) {
      chain_.log(4, fmt::format("unit {}: overflow mode not set: {}", unit, r.text));
    } else {
      co_return r;
    }
  } else if (state.mode == 2) {
    chain_.log(4, fmt::format("unit {} is in Program Mode (M2); motor and I/O requests are "
                              "refused until it leaves it",
                              unit));
  }
  state.set_up = true;
  co_return std::nullopt;
}

asio::awaitable<Reply> CententFamily::kill(Link& link, int unit, const LinkTiming& timing) {
  cn0170::Plan plan = cn0170::plan_kill(chain_, options_, unit, configured_units());
  const int first = *plan.reply_unit;
  Reply reply = co_await run(link, unit, std::move(plan), "K", timing);
  if (reply.status == Reply::Status::ok) {
    chain_.log(4, fmt::format("kill (K) sent from unit {} down the chain", first));
    co_return reply;
  }
  if (options_.kill_target == cn0170::Options::KillTarget::first_unit) {
    // The first unit did not confirm: the K may not have started down the chain. Send it to
    // every unit the gateway knows; each relays it further.
    cn0170::Options every = options_;
    every.kill_target = cn0170::Options::KillTarget::every_unit;
    Reply again = co_await run(
        link, unit, cn0170::plan_kill(chain_, every, unit, configured_units()), "K", timing);
    chain_.log(
        3, fmt::format("kill: unit {} did not confirm ({}); K sent to every unit: {}", first,
                       reply.text, again.status == Reply::Status::ok ? "confirmed" : again.text));
    co_return again;
  }
  co_return reply;
}

asio::awaitable<Reply> CententFamily::local_read(Link& link, int unit, const Request& request,
                                                 const LinkTiming& timing) {
  if (request.command != cn0170::kCountersRequest)
    co_return Reply::of(Reply::Status::device_error,
                        "unknown gateway-local read '" + request.command + "'",
                        cn0170::kInvalidValue);
  // Counters are the gateway's, but a unit that stopped answering must not look online.
  if (!chain_.units[static_cast<std::size_t>(unit)].answering) {
    const Request probe{"M?", Request::Expect::values, NumberFormat::decimal};
    Reply answer =
        co_await run(link, unit, cn0170::plan_request(chain_, options_, unit, probe), "M?", timing);
    if (answer.status != Reply::Status::ok) co_return answer;
  }
  Reply r = Reply::of(Reply::Status::ok);
  r.values = cn0170::counters_of(chain_, unit);
  co_return r;
}

asio::awaitable<Reply> CententFamily::transact(Link& link, const NodeAddress& node,
                                               const Request& request, const LinkTiming& timing) {
  const int unit = node.number;
  Reply reply;
  if (!request.command.empty() && request.command.front() == '@') {
    reply = co_await local_read(link, unit, request, timing);
  } else if (request.bus_wide) {
    reply = co_await kill(link, unit, timing);
  } else {
    std::optional<Reply> failed = co_await set_up(link, unit, timing);
    if (failed) {
      reply = std::move(*failed);
    } else {
      cn0170::Plan plan = cn0170::plan_request(chain_, options_, unit, request);
      reply = co_await run(link, unit, std::move(plan), request.command, timing);
    }
  }
  // The next reply of a unit that reset (its U<n> may have come during another unit's exchange)
  // tells the bus: every command the unit ran before is lost.
  auto& state = chain_.units[static_cast<std::size_t>(unit)];
  reply.controller_reset = std::exchange(state.reset_unreported, false);
  flush_log(link);
  co_return reply;
}

std::size_t CententFamily::estimate_wire_chars(const NodeAddress&, const Request& request) const {
  if (!request.command.empty() && request.command.front() == '@') return 0;
  // Leading CR, the request and its CR, and on average half a selection (sticky for reads).
  std::size_t chars = 1 + request.command.size() + 1 + 2;
  std::size_t replies = 0;
  for (const auto& part : cn0170::split_instructions(request.command)) {
    const auto q = cn0170::classify_query(part);
    if (!q) continue;
    // Prefix digit, key, '=', value, 'h', CR: "2X=00C0E6B6h\r" is 13.
    replies += q->kind == MessageKind::position ? 13 : q->kind == MessageKind::mode ? 4 : 9;
  }
  if (request.expect == Request::Expect::ack) {
    chars += 4;  // commands select explicitly
    if (options_.confirm_commands) {
      chars += 3;    // M?\r
      replies += 4;  // 2M1\r
    }
  }
  return chars + replies;
}

FamilyPtr make_centent_cn0170_family() {
  return std::make_shared<CententFamily>();
}

}  // namespace fieldgate
