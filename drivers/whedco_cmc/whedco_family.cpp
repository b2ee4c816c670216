#include "drivers/whedco_cmc/whedco_family.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "drivers/ascii_blanks.hpp"
#include "drivers/printable_bytes.hpp"

namespace fieldgate {

namespace {

using whedco::EchoMode;
using whedco::QueryKind;

bool has_control_bytes(std::string_view s) {
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if ((u < 0x20 && c != '\r' && c != '\n' && c != '\t') || u >= 0x7f) return true;
  }
  return false;
}

bool has_text(std::string_view s) {
  for (const char c : s)
    if ((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '?') return true;
  return false;
}

Reply garbled(std::string text) {
  return Reply::of(Reply::Status::garbled, std::move(text));
}

Reply rejected(std::string_view body, std::string_view line) {
  return Reply::of(Reply::Status::device_error,
                   fmt::format("unit answered '{}' to '{}'", printable_bytes(body), line),
                   whedco::kRejected);
}

Reply refused(std::string text) {
  return Reply::of(Reply::Status::device_error, "not sent: " + std::move(text),
                   whedco::kRefusedByGateway);
}

bool is_axis(char c) {
  return c == 'W' || c == 'X' || c == 'Y' || c == 'Z';
}

bool is_hex(char c) {
  return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'F');
}

// Commands that answer with a value (§3.8, §3.7, §5.3.1): what a read may send.
bool is_query(std::string_view t) {
  if (t.ends_with('?')) return true;
  if (t == "RS" || t == "FC" || t == "RDI" || t == "RDB") return true;
  if (t.size() == 3 && is_axis(t[2]) &&
      (t.starts_with("RS") || t.starts_with("RC") || t.starts_with("RP") || t.starts_with("FE") ||
       t.starts_with("FC")))
    return true;
  return t.size() == 3 && t.starts_with("RA") && is_hex(t[2]);  // RAd: analog input d
}

}  // namespace

EchoMode WhedcoFamily::echo_mode(const NodeAddress& node) {
  switch (node.axis) {
    case 'e':
      return EchoMode::echo;
    case 'n':
      return EchoMode::non_echo;
    default:
      return EchoMode::automatic;
  }
}

std::optional<NodeAddress> WhedcoFamily::parse_address(std::string_view text,
                                                       std::string& error) const {
  const auto a = whedco::parse_address(text, error);
  if (!a) return std::nullopt;
  // The canonical text is the address digit alone, so two nodes on one unit are caught however
  // their formats are written.
  NodeAddress n = NodeAddress::numbered(a->unit);
  n.axis = a->mode == EchoMode::echo ? 'e' : (a->mode == EchoMode::non_echo ? 'n' : 0);
  return n;
}

void WhedcoFamily::validate_model(const Model& model, Diagnostics& diagnostics) const {
  check_model_options(model, name(), model_options(), diagnostics,
                      "the communication format is set per node in 'address', e.g. 4/non-echo; "
                      "reply layouts by each read's 'format' and 'field'");
  const auto render = [](const CommandTemplate& t) {
    return t.render([](std::string_view) { return int64_t{1}; });
  };
  const auto check = [&](const CommandTemplate& t, const SourceMark& mark, const std::string& what,
                         bool query) {
    std::string error;
    const auto prepared = whedco::prepare_command(render(t), error);
    if (!prepared) {
      diagnostics.error(mark, fmt::format("{}: {}", what, error));
      return;
    }
    if (query && !is_query(prepared->text))
      diagnostics.error(mark, fmt::format("{}: '{}' is no query (a load command with '?', Vd=?, "
                                          "RS, RSa, RPa, RCa, FEa, FC, FCa, RAd, RDI, RDB)",
                                          what, t.source()));
    if (!query && is_query(prepared->text))
      diagnostics.error(mark, fmt::format("{}: '{}' is a query; its value would not be the "
                                          "prompt the command waits for",
                                          what, t.source()));
  };
  for (const auto& p : model.points) {
    if (p.read) {
      if (p.read->object)
        diagnostics.error(p.mark,
                          fmt::format("point {}: objects are for the canopen family", p.name));
      else
        check(p.read->request, p.mark, "point " + p.name + " read", true);
      if (p.read->format == NumberFormat::hex24)
        diagnostics.error(p.mark, fmt::format("point {}: Whedco replies are decimal or hex; "
                                              "hex24 does not apply",
                                              p.name));
    }
    if (p.write) {
      if (p.write->object)
        diagnostics.error(p.mark,
                          fmt::format("point {}: objects are for the canopen family", p.name));
      else
        check(p.write->request, p.mark, "point " + p.name + " write", false);
    }
  }
  for (const auto& a : model.actions) {
    if (a.bus_wide)
      diagnostics.error(a.mark, fmt::format("action {}: Whedco CMC units have no broadcast "
                                            "address; give each unit its own action",
                                            a.name));
    for (const auto& s : a.steps) {
      if (s.kind != ActionStep::Kind::send) continue;
      check(s.command, s.mark, "action " + a.name, false);
      if (s.urgent)
        diagnostics.error(s.mark, fmt::format("action {}: whedco-cmc has no urgent commands; "
                                              "a Whedco exchange never holds the line",
                                              a.name));
    }
  }
}

Reply interpret_whedco_reply(const WhedcoExchange& x, std::string_view frame,
                             WhedcoFindings* findings) {
  WhedcoFindings ignored;
  WhedcoFindings& found = findings ? *findings : ignored;
  found = {};
  bool echoed = false;
  std::string_view body = whedco::strip_echo(frame, x.line, echoed);
  const auto prompt = body.rfind(whedco::kPrompt);
  if (prompt == std::string_view::npos)
    return garbled("no '*' prompt in '" + printable_bytes(frame) + "'");
  body = trim_blanks(body.substr(0, prompt));
  if (x.mode == EchoMode::echo && !echoed)
    return garbled(
        fmt::format("no echo of '{}' before '{}': is the unit set to non-echo "
                    "(SW2-5)?",
                    x.line, printable_bytes(frame)));
  if (x.mode == EchoMode::non_echo && echoed)
    return garbled(
        fmt::format("the unit echoed '{}': it is set to echo (SW2-5), the node to "
                    "non-echo",
                    x.line));
  if (has_control_bytes(body)) return garbled("'" + printable_bytes(frame) + "'");
  // An echo that went wrong on the line: the unit's address followed by a mnemonic.
  if (!echoed && x.mode != EchoMode::non_echo && body.size() >= 2 && body[0] == x.line[0] &&
      ((body[1] >= 'A' && body[1] <= 'Z') || body[1] == '!'))
    return garbled(fmt::format("corrupted echo '{}' of '{}'", printable_bytes(frame), x.line));

  if (x.expect == Request::Expect::ack) {
    if (!body.empty()) return rejected(body, x.line);
    return Reply::of(Reply::Status::ok);
  }
  if (body.empty()) return garbled(fmt::format("prompt without a value for '{}'", x.line));

  Reply r = Reply::of(Reply::Status::ok);
  switch (x.kind) {
    case QueryKind::axis_fault: {
      std::optional<int64_t> code;
      if (const auto numbers = whedco::parse_numbers(body, true); numbers && numbers->size() == 1)
        code = numbers->front().mantissa;
      else if (const auto from_text = whedco::axis_fault_from_text(body))
        code = *from_text;
      if (!code) return has_text(body) ? rejected(body, x.line) : garbled(printable_bytes(frame));
      r.values = {*code, *code != whedco::kAxisFunctional ? 1 : 0};
      return r;
    }
    case QueryKind::unit_fault: {
      std::optional<int64_t> code;
      const bool hex = x.format == NumberFormat::hex;
      bool number = false;
      if (const auto numbers = whedco::parse_numbers(body, hex);
          numbers && numbers->size() == 1 && numbers->front().decimals == 0) {
        code = numbers->front().mantissa;
        number = true;
      } else {
        code = whedco::unit_fault_from_text(body);
      }
      if (!code) return has_text(body) ? rejected(body, x.line) : garbled(printable_bytes(frame));
      found.unit_fault_number = number;
      bool functional = *code == whedco::kUnitFunctional;
      // Non-echo numbers: the excerpt gives no base numbers. 0 (base x 256 + axis byte) and 8
      // (the FCa table's Unit Functional) are both read as functional until a WB shows which.
      if (number)
        functional = x.unit_functional
                         ? *code == *x.unit_functional
                         : (*code == whedco::kUnitFunctional || *code == whedco::kAxisFunctional);
      r.values = {*code, functional ? 0 : 1};
      return r;
    }
    case QueryKind::status_word: {
      std::string problem;
      const auto word = whedco::parse_status_word(
          body, x.format == NumberFormat::hex ? whedco::StatusForm::hex : x.status_form, problem);
      if (!word) return garbled(problem);
      found.status_form = word->evidence;
      r.values = {word->value};
      return r;
    }
    case QueryKind::bit_list:
      if (const auto bits = whedco::parse_bit_string(body)) {
        r.values = {*bits};
        return r;
      }
      break;
    case QueryKind::plain:
      break;
  }
  const auto numbers = whedco::parse_numbers(body, x.format == NumberFormat::hex);
  if (!numbers || numbers->empty())
    return has_text(body) ? rejected(body, x.line) : garbled("'" + printable_bytes(frame) + "'");
  for (const auto& n : *numbers) {
    const auto v = whedco::to_internal(n, x.unit_ratio);
    if (!v) return garbled(fmt::format("value '{}' out of range", printable_bytes(body)));
    r.values.push_back(*v);
  }
  return r;
}

asio::awaitable<void> WhedcoFamily::resync(Link& link, const LinkTiming& timing) {
  const bool drain = resync_ == Resync::void_and_drain;
  resync_ = Resync::none;
  link.discard_input();
  const auto ec = co_await link.send(whedco::kLineVoid);
  if (ec) co_return;  // the request that follows reports the broken link
  // A unit holding part of a line now ignores it and prompts; after a garbled reply, whatever
  // is still on its way is waited out too, so it cannot pass for the next reply.
  LinkTiming wait = timing;
  if (!drain) wait.reply_timeout = timing.byte_timeout;
  const FrameSplitter until_prompt = [drain](std::string_view b) -> std::size_t {
    if (drain) return 0;
    const auto p = b.find(whedco::kPrompt);
    return p == std::string_view::npos ? 0 : p + 1;
  };
  const LinkRead read = co_await link.read_frame(until_prompt, wait);
  (void)read;
  link.discard_input();
}

namespace {

// One step of the proof: `line` sent, its answer read up to the prompt; `with_text` whether the
// answer has text before the prompt (a value) or is the prompt alone.
AlignmentStep proof_step(const std::string& line, EchoMode mode, bool with_text) {
  AlignmentStep step;
  step.request = line + whedco::kTerminator;
  step.splitter = [line, mode](std::string_view buffer) {
    return whedco::frame_length(buffer, line, mode);
  };
  step.matches = [line, mode, with_text](std::string_view frame) {
    bool echoed = false;
    std::string_view body = whedco::strip_echo(frame, line, echoed);
    if ((mode == EchoMode::echo && !echoed) || (mode == EchoMode::non_echo && echoed)) return false;
    if (has_control_bytes(frame)) return false;
    const auto prompt = body.find(whedco::kPrompt);
    if (prompt == std::string_view::npos || prompt + 1 != body.size()) return false;
    return trim_blanks(body.substr(0, prompt)).empty() != with_text;
  };
  step.expected = with_text ? "a value before the '*' prompt" : "the '*' prompt alone";
  return step;
}

}  // namespace

std::optional<AlignmentProof> WhedcoFamily::alignment_proof(NodeContext& context,
                                                            const LinkTiming&) {
  const NodeAddress& node = context.address();
  const EchoMode mode = echo_mode(node);
  AlignmentProof proof;
  proof.name = fmt::format("{}! -> '*', {}FC -> a value and '*'", node.number, node.number);
  // A `!` anywhere in a line makes the unit ignore it (§5.17): the prompt alone comes back.
  proof.steps.push_back(proof_step(whedco::sent_line(node.number, "!"), mode, false));
  // FC answers in every state and format, with a value (non-echo) or text (echo).
  proof.steps.push_back(proof_step(whedco::sent_line(node.number, "FC"), mode, true));
  return proof;
}

const ModelOptionSpecs& WhedcoFamily::model_options() const {
  static const ModelOptionSpecs specs{
      choice_option("status_layout", "busy_first", {"busy_first", "outputs"},
                    "bit order of RS status words (the manual's section 4.3.1 is missing): busy "
                    "at bit 0 and fault at bit 1 (busy_first, the models' bits), or the hardware "
                    "outputs' order (set point A, B, busy, fault). Not detected: bit 2 may be "
                    "busy in one layout and another state (homed) in the other"),
  };
  return specs;
}

NodeContextPtr WhedcoFamily::bind_node(const NodeAddress& node, const Model& model) {
  Diagnostics reported;  // validate_model reported them; a model with errors never runs
  const std::string layout =
      check_model_options(model, name(), model_options(), reported).text("status_layout");
  auto bound = std::make_shared<BoundNode>(node);
  bound->layout =
      layout == "outputs" ? whedco::StatusLayout::outputs : whedco::StatusLayout::busy_first;
  return bound;
}

asio::awaitable<void> WhedcoFamily::on_link_open(Link& link, const LinkTiming& timing) {
  // The port may have been closed for a while: unit ratios may have changed, and a unit may hold
  // part of a line from before.
  unit_ratios_.clear();
  contacted_.clear();
  unit_functional_.clear();
  resync_ = Resync::void_and_drain;
  co_await resync(link, timing);
}

asio::awaitable<Reply> WhedcoFamily::exchange(Link& link, const BoundNode& bound,
                                              const std::string& command, Request::Expect expect,
                                              NumberFormat format, QueryKind kind, int unit_ratio,
                                              const LinkTiming& timing) {
  const NodeAddress& node = bound.address();
  if (resync_ != Resync::none) co_await resync(link, timing);
  // Replies carry no address: anything left over from an earlier exchange would pass for this
  // one's reply.
  link.discard_input();
  WhedcoExchange x;
  x.line = whedco::sent_line(node.number, command);
  if (const auto f = status_forms_.find(node.number); f != status_forms_.end())
    x.status_form = f->second;
  if (const auto u = unit_functional_.find(node.number); u != unit_functional_.end())
    x.unit_functional = u->second;
  x.mode = echo_mode(node);
  x.expect = expect;
  x.format = format;
  x.kind = kind;
  x.unit_ratio = unit_ratio;
  const std::error_code ec = co_await link.send(x.line + whedco::kTerminator);
  if (ec) co_return Reply::of(Reply::Status::link_down, ec.message());
  const std::string line = x.line;
  const EchoMode mode = x.mode;
  const FrameSplitter splitter = [line, mode](std::string_view buffer) {
    return whedco::frame_length(buffer, line, mode);
  };
  // After its echo a unit executes the command before it answers (2 ms on average, position
  // reads 5-10 ms, A.2): that pause is bounded by the reply timeout, not the byte timeout.
  LinkTiming read_timing = timing;
  if (mode != EchoMode::non_echo)
    read_timing.byte_timeout = std::max(timing.byte_timeout, timing.reply_timeout);
  const LinkRead read = co_await link.read_frame(splitter, read_timing);
  switch (read.status) {
    case LinkRead::Status::frame: {
      Reply r = interpret_whedco_reply(x, read.frame, &findings_);
      if (r.status == Reply::Status::garbled) resync_ = Resync::void_and_drain;
      if (findings_.status_form && findings_.status_form != x.status_form) {
        status_forms_[node.number] = *findings_.status_form;
        link.note(fmt::format("whedco-cmc unit {}: status words are printed in {} (reply to '{}')",
                              node.number, whedco::to_string(*findings_.status_form), x.line));
      }
      if (kind == QueryKind::status_word && r.status == Reply::Status::ok && !r.values.empty())
        r.values[0] = whedco::to_model_layout(r.values[0], bound.layout);
      co_return r;
    }
    case LinkRead::Status::timeout:
      // A slow unit's late reply must not pass for the next one: wait it out too.
      resync_ = Resync::void_and_drain;
      if (read.partial.empty()) co_return Reply::of(Reply::Status::timeout, "no reply");
      co_return Reply::of(Reply::Status::garbled,
                          "incomplete reply '" + printable_bytes(read.partial) + "'");
    case LinkRead::Status::overflow:
      resync_ = Resync::void_and_drain;
      co_return Reply::of(Reply::Status::garbled,
                          "reply longer than any Whedco reply, no '*' prompt");
    case LinkRead::Status::error:
      co_return Reply::of(Reply::Status::link_down, read.error.message());
  }
  co_return Reply{};
}

std::optional<int> WhedcoFamily::known_unit_ratio(int unit,
                                                  const whedco::PreparedCommand& prepared) const {
  if (prepared.quantity == whedco::Quantity::none) return 1;
  const auto it = unit_ratios_.find(std::make_pair(unit, prepared.axis));
  if (it == unit_ratios_.end()) return std::nullopt;
  return it->second;
}

std::optional<std::string> WhedcoFamily::pipelined_request(NodeContext& context,
                                                           const Request& request) {
  // transact_node() would send this line with no exchange before it: no first contact, no UR?
  // and no resync.
  const int unit = context.address().number;
  if (request.bus_wide || resync_ != Resync::none) return std::nullopt;
  if (const auto c = contacted_.find(unit); c == contacted_.end() || !c->second)
    return std::nullopt;
  std::string error;
  const auto prepared = whedco::prepare_command(request.command, error);
  if (!prepared) return std::nullopt;
  const auto ratio = known_unit_ratio(unit, *prepared);
  if (!ratio) return std::nullopt;
  return whedco::encode_command(unit, whedco::wire_command(*prepared, *ratio));
}

asio::awaitable<Reply> WhedcoFamily::transact_node(Link& link, NodeContext& context,
                                                   const Request& request,
                                                   const LinkTiming& timing) {
  // Every context this family's transact() receives is one its bind_node() made.
  const auto& bound = static_cast<const BoundNode&>(context);
  const NodeAddress& node = bound.address();
  if (request.bus_wide)
    co_return refused(
        fmt::format("'{}' for every unit: Whedco CMC units have no broadcast "
                    "address",
                    request.command));
  std::string error;
  const auto prepared = whedco::prepare_command(request.command, error);
  if (!prepared) co_return refused(error);
  const bool was_contacted = contacted_[node.number];
  bool power_cycled = false;
  if (!was_contacted) power_cycled = co_await first_contact(link, bound, timing);

  std::optional<int> known = known_unit_ratio(node.number, *prepared);
  if (!known) {
    const std::string query = std::string("UR") + prepared->axis + "?";
    Reply ur = co_await exchange(link, bound, query, Request::Expect::values, NumberFormat::decimal,
                                 QueryKind::plain, 1, timing);
    if (ur.status != Reply::Status::ok) {
      ur.text =
          fmt::format("reading the unit ratio of axis {} ({}): {}", prepared->axis, query, ur.text);
      co_return ur;
    }
    if (ur.values.size() != 1 || ur.values[0] < whedco::kMinUnitRatio ||
        ur.values[0] > whedco::kMaxUnitRatio)
      co_return garbled(
          fmt::format("unit ratio of axis {} is not a whole number 1..10000", prepared->axis));
    known = static_cast<int>(ur.values[0]);
    unit_ratios_.emplace(std::make_pair(node.number, prepared->axis), *known);
  }
  const int ratio = *known;
  const std::string wire = whedco::wire_command(*prepared, ratio);
  Reply r = co_await exchange(link, bound, wire, request.expect, request.format, prepared->kind,
                              prepared->scaled_reply ? ratio : 1, timing);
  if (was_contacted) note_power_failure(link, node.number, *prepared, r);
  if (power_cycled) r.controller_reset = true;
  if (r.status == Reply::Status::ok && prepared->unit_ratio_axis) {
    const auto key = std::make_pair(node.number, *prepared->unit_ratio_axis);
    if (prepared->unit_ratio_written) {
      unit_ratios_[key] = static_cast<int>(*prepared->unit_ratio_written);
    } else if (r.values.size() == 1 && r.values[0] >= whedco::kMinUnitRatio &&
               r.values[0] <= whedco::kMaxUnitRatio) {
      unit_ratios_[key] = static_cast<int>(r.values[0]);
    }
  }
  co_return r;
}

// Power Failure read from a unit whose power-up state was cleared at first contact: the unit
// was power-cycled since, and every command it ran is lost. Reported once per power failure;
// the unit stays faulted until clear_faults (WB), as the PLC's reset sends it.
void WhedcoFamily::note_power_failure(Link& link, int unit, const whedco::PreparedCommand& prepared,
                                      Reply& reply) {
  if (reply.status != Reply::Status::ok || reply.values.empty()) return;
  bool power_failure = false;
  if (prepared.kind == whedco::QueryKind::axis_fault)
    power_failure = reply.values[0] == 0;  // §6.2 code 0 in either reading
  else if (prepared.kind == whedco::QueryKind::unit_fault && !findings_.unit_fault_number)
    power_failure = reply.values[0] >> 8 == whedco::kUnitPowerFailure >> 8;  // echo text
  else
    return;  // a non-echo FC number: its Power Failure base is not in the excerpt
  bool& reported = power_failure_reported_[unit];
  if (!power_failure) {
    if (prepared.kind == whedco::QueryKind::unit_fault ||
        reply.values[0] == whedco::kAxisFunctional)
      reported = false;
    return;
  }
  if (reported) return;
  reported = true;
  reply.controller_reset = true;
  link.note(
      fmt::format("whedco-cmc unit {}: '{}' reads Power Failure after first contact: the unit was "
                  "power-cycled (clear_faults sends WB)",
                  unit, prepared.text));
}

asio::awaitable<bool> WhedcoFamily::first_contact(Link& link, const BoundNode& bound,
                                                  const LinkTiming& timing) {
  const NodeAddress& node = bound.address();
  // Named commands: exchange() keeps a reference to its command across suspensions.
  const std::string fc_command = "FC";
  const std::string wb_command = "WB";
  const auto read_fc = [&]() {
    return exchange(link, bound, fc_command, Request::Expect::values, NumberFormat::decimal,
                    QueryKind::unit_fault, 1, timing);
  };
  const Reply fc = co_await read_fc();
  if (fc.status != Reply::Status::ok || fc.values.size() != 2) co_return false;  // try again later
  contacted_[node.number] = true;
  // A unit met before (the link was reopened since) that reads its power-up state again was
  // power-cycled while the gateway could not see it.
  const auto before = power_failure_reported_.find(node.number);
  const bool known = before != power_failure_reported_.end() && !before->second;
  if (fc.values[1] == 0) {
    power_failure_reported_[node.number] = false;
    co_return false;
  }
  const int64_t code = fc.values[0];
  const bool number = findings_.unit_fault_number;
  // Power-up: "Power Failure" (echo text, or base 1 in the high byte). A non-echo number of
  // another reading (an axis byte without that base) counts only if every axis it names reports
  // code 0, Power Failure (FCa codes are the same in every reading): a real fault is left alone.
  const int64_t base = code >> 8;
  bool power_up = base == 1;
  if (number && base == 0 && (code & 0xff) != 0) {
    power_up = true;
    constexpr std::string_view kByteAxes = "XYWZ";  // bits 0-3 (and 4-7) of the axis byte
    for (std::size_t i = 0; i < kByteAxes.size() && power_up; ++i) {
      if (!(code & (int64_t{0x11} << i))) continue;
      const std::string axis_command = std::string("FC") + kByteAxes[i];
      const Reply axis = co_await exchange(link, bound, axis_command, Request::Expect::values,
                                           NumberFormat::decimal, QueryKind::axis_fault, 1, timing);
      power_up = axis.status == Reply::Status::ok && !axis.values.empty() && axis.values[0] == 0;
    }
  }
  // The power-up state found here is the one first contact clears, not a power cycle since.
  power_failure_reported_[node.number] = power_up;
  const bool power_cycled = known && power_up;
  if (!power_up) {
    link.note(
        fmt::format("whedco-cmc unit {}: faulted at first contact (FC {}); not cleared: "
                    "clear_faults sends WB",
                    node.number, code));
    co_return false;
  }
  const Reply wb = co_await exchange(link, bound, wb_command, Request::Expect::ack,
                                     NumberFormat::decimal, QueryKind::plain, 1, timing);
  if (wb.status != Reply::Status::ok) {
    link.note(fmt::format("whedco-cmc unit {}: power-up state (FC {}); WB failed: {}", node.number,
                          code, wb.text.empty() ? to_string(wb.status) : wb.text));
    co_return power_cycled;
  }
  const Reply after = co_await read_fc();
  std::string learned;
  if (after.status == Reply::Status::ok && !after.values.empty() && findings_.unit_fault_number &&
      (after.values[0] == whedco::kUnitFunctional || after.values[0] == whedco::kAxisFunctional)) {
    unit_functional_[node.number] = after.values[0];
    learned = fmt::format("; non-echo FC reads Unit Functional as {}", after.values[0]);
  }
  link.note(fmt::format(
      "whedco-cmc unit {}: power-up state at first contact (FC {}): sent WB{}{}", node.number, code,
      after.status == Reply::Status::ok && after.values.size() == 2 && after.values[1] != 0
          ? fmt::format(", still faulted (FC {})", after.values[0])
          : std::string(),
      learned));
  co_return power_cycled;
}

std::size_t WhedcoFamily::estimate_wire_chars(const NodeAddress& node,
                                              const Request& request) const {
  const std::size_t line = request.command.size() + 2;
  // Auto-detected units are counted as echoing: the factory setting, and the larger cost.
  const std::size_t echo = echo_mode(node) == EchoMode::non_echo ? 0 : line + 1;
  // "-8388607.1234\r\n*" or "*".
  const std::size_t reply = request.expect == Request::Expect::values ? 16 : 1;
  return line + echo + reply;
}

}  // namespace fieldgate

namespace fieldgate {
FamilyPtr make_whedco_cmc_family() {
  return std::make_shared<WhedcoFamily>();
}
}  // namespace fieldgate
