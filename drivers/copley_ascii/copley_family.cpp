#include "drivers/copley_ascii/copley_family.hpp"

#include <fmt/format.h>

#include "drivers/copley_ascii/copley_codec.hpp"

namespace fieldgate {

std::optional<NodeAddress> CopleyFamily::parse_address(std::string_view text,
                                                       std::string& error) const {
  auto a = copley::parse_address(text, error);
  if (!a) return std::nullopt;
  NodeAddress n;
  n.number = a->node;
  n.axis = a->axis;
  n.text = std::to_string(a->node) + (a->axis ? std::string(".") + a->axis : std::string());
  return n;
}

void CopleyFamily::validate_model(const Model& model, Diagnostics& diagnostics) const {
  check_model_options(model, name(), model_options(), diagnostics);
  const auto check = [&](const CommandTemplate& t, const SourceMark& mark,
                         const std::string& what) {
    const std::string& s = t.source();
    if (s.empty()) return;
    if (s.find('\r') != std::string::npos || s.find('\n') != std::string::npos)
      diagnostics.error(mark,
                        fmt::format("{}: the family adds the CR; remove it from '{}'", what, s));
    if (s.find("  ") != std::string::npos || s.front() == ' ' || s.back() == ' ')
      diagnostics.error(mark, fmt::format("{}: Copley commands take exactly one space between "
                                          "tokens (manual §2.1): '{}'",
                                          what, s));
    const char code = s.front();
    if (std::string_view("sgctri").find(code) == std::string_view::npos ||
        (s.size() > 1 && s[1] != ' '))
      diagnostics.error(mark, fmt::format("{}: '{}' does not start with a Copley command code "
                                          "(s, g, c, t, r, i) and a space",
                                          what, s));
  };
  for (const auto& p : model.points) {
    if (p.read) {
      check(p.read->request, p.mark, "point " + p.name + " read");
      if (p.read->format != NumberFormat::decimal)
        diagnostics.error(p.mark, fmt::format("point {}: Copley replies are decimal", p.name));
      if (p.read->object)
        diagnostics.error(p.mark,
                          fmt::format("point {}: objects are for the canopen family", p.name));
    }
    if (p.write) check(p.write->request, p.mark, "point " + p.name + " write");
  }
  for (const auto& a : model.actions)
    for (const auto& s : a.steps)
      if (s.kind == ActionStep::Kind::send) check(s.command, s.mark, "action " + a.name);
}

NodeContextPtr CopleyFamily::bind_node(const NodeAddress& node, const Model& model) {
  if (node.number == 0 && node.axis != 0 && gateway_axis_ == 0) gateway_axis_ = node.axis;
  return ProtocolFamily::bind_node(node, model);
}

namespace {

constexpr unsigned kPowerUpBaud = 9600;

// What a rate probe found. Any well-formed reply, an error included, proves the amplifier hears
// us at this rate: a multi-axis amplifier that wants an axis letter answers `g r0x90` with
// e 33, and that is still an answer.
struct Probe {
  bool answered = false;
  bool wants_axis = false;  // e 33 to the plain form, a value to `.a g r0x90`
  std::string heard;        // for the log: what came back, if anything
};

asio::awaitable<copley::ParsedReply::Kind> probe_once(Link& link, const LinkTiming& timing,
                                                      std::string_view command,
                                                      std::string& heard) {
  link.discard_input();
  if (co_await link.send(std::string(command) + "\r"))
    co_return copley::ParsedReply::Kind::malformed;
  const auto read = co_await link.read_frame(copley::frame_length, timing);
  if (read.status != LinkRead::Status::frame) {
    heard = read.partial.empty() ? "no reply" : "'" + read.partial + "'";
    // A late or partial reply must not answer the next probe.
    const auto guard = guard_time(timing, link.char_time_us());
    co_await link.resync(guard, 10 * guard);
    co_return copley::ParsedReply::Kind::malformed;
  }
  heard = "'" + read.frame.substr(0, read.frame.size() - 1) + "'";
  co_return copley::parse_reply(read.frame).kind;
}

asio::awaitable<Probe> probe_rate(Link& link, const LinkTiming& timing) {
  Probe p;
  const auto plain = co_await probe_once(link, timing, "g r0x90", p.heard);
  if (plain == copley::ParsedReply::Kind::values) {
    p.answered = true;
    co_return p;
  }
  // A multi-axis amplifier may answer a command without axis letter with e 33, or not at all
  // (the manual only says the letter is necessary): does the axis form work?
  std::string heard;
  const auto axis = co_await probe_once(link, timing, ".a g r0x90", heard);
  p.wants_axis = axis == copley::ParsedReply::Kind::values;
  p.answered = p.wants_axis || plain != copley::ParsedReply::Kind::malformed;
  co_return p;
}

}  // namespace

asio::awaitable<void> CopleyFamily::on_link_open(Link& link, const LinkTiming& timing) {
  auto& transport = link.transport();
  const unsigned configured = transport.baud();
  if (configured == 0 || configured == kPowerUpBaud) co_return;
  const Probe at_configured = co_await probe_rate(link, timing);
  if (at_configured.answered) {  // already at the configured rate
    gateway_wants_axis_ = at_configured.wants_axis;
    co_return;
  }
  if (transport.set_baud(kPowerUpBaud)) co_return;  // not a real UART: nothing to switch
  const Probe at_power_up = co_await probe_rate(link, timing);
  if (!at_power_up.answered) {
    transport.set_baud(configured);
    link.note(
        fmt::format("Copley gateway amplifier does not answer at {} baud ({}) nor at its "
                    "power-up rate {} ({}); staying at {}",
                    configured, at_configured.heard, kPowerUpBaud, at_power_up.heard, configured));
    co_return;
  }
  gateway_wants_axis_ = at_power_up.wants_axis;
  // §4.1: send the new rate, switch the host as soon as the CR has left, expect ok at the new
  // rate, then wait 100 ms before anything else. A multi-axis amplifier gets the axis form.
  link.discard_input();
  const std::string prefix = at_power_up.wants_axis ? ".a " : "";
  const auto ec = co_await link.send(prefix + fmt::format("s r0x90 {}\r", configured));
  transport.drain();
  transport.set_baud(configured);
  if (ec) co_return;
  const auto read = co_await link.read_frame(copley::frame_length, timing);
  co_await link.pause(std::chrono::milliseconds(100));
  const bool ok = read.status == LinkRead::Status::frame &&
                  copley::parse_reply(read.frame).kind == copley::ParsedReply::Kind::ok;
  link.note(ok ? fmt::format("Copley gateway amplifier switched from {} to {} baud{}", kPowerUpBaud,
                             configured, at_power_up.wants_axis ? " (it wants an axis letter)" : "")
               : fmt::format("Copley gateway amplifier did not confirm the switch to {} baud",
                             configured));
}

std::optional<AlignmentProof> CopleyFamily::alignment_proof(NodeContext&, const LinkTiming&) {
  const char axis = gateway_axis_ != 0 ? gateway_axis_ : gateway_wants_axis_ ? 'a' : 0;
  const std::string prefix = axis != 0 ? std::string(".") + axis + " " : std::string();
  AlignmentProof proof;
  proof.name = "g f0x32 -> e 15, g r0x90 -> a baud rate";
  proof.steps.push_back({prefix + "g f0x32\r", copley::frame_length,
                         [](std::string_view frame) {
                           const auto r = copley::parse_reply(frame);
                           return r.kind == copley::ParsedReply::Kind::error &&
                                  r.values.front() == 15;
                         },
                         "'e 15'"});
  // 0x90 reads back the nearest rate the amplifier's clock allows (§4.1 step 4), which need not
  // be the host's (a serial device server, a PTY): any rate in the amplifier's range.
  proof.steps.push_back({prefix + "g r0x90\r", copley::frame_length,
                         [](std::string_view frame) {
                           const auto r = copley::parse_reply(frame);
                           return r.kind == copley::ParsedReply::Kind::values &&
                                  r.values.size() == 1 && r.values.front() >= 9000 &&
                                  r.values.front() <= 120000;
                         },
                         "'v <baud rate>'"});
  return proof;
}

Reply interpret_copley_reply(const NodeAddress& node, const Request& request,
                             std::string_view line) {
  // Replies carry no address: a reply is this request's only if nothing else could have
  // produced it. What the command code allows decides; the request's own expectation is the
  // fallback for codes the digest does not list.
  auto expected = copley::expected_reply(request.command);
  if (expected.kind == copley::ExpectedReply::Kind::unknown)
    expected.kind = request.expect == Request::Expect::ack ? copley::ExpectedReply::Kind::ok
                                                           : copley::ExpectedReply::Kind::values;
  const auto parsed = copley::parse_reply(line);
  const auto garbled = [&](std::string why) {
    return Reply::of(Reply::Status::garbled, fmt::format("{} to '{}'", why, request.command));
  };
  const auto with_values = [&] {
    Reply reply = Reply::of(Reply::Status::ok);
    reply.values = parsed.values;
    return reply;
  };
  switch (parsed.kind) {
    case copley::ParsedReply::Kind::ok:
      if (expected.kind == copley::ExpectedReply::Kind::ok) return Reply::of(Reply::Status::ok);
      return garbled("'ok' where a value was expected");
    case copley::ParsedReply::Kind::values:
      if (expected.kind != copley::ExpectedReply::Kind::values)
        return garbled("a value where 'ok' was expected");
      if (expected.count != 0 && parsed.values.size() != expected.count)
        return garbled(fmt::format("{} value(s) where {} were expected", parsed.values.size(),
                                   expected.count));
      return with_values();
    case copley::ParsedReply::Kind::register_value:
      if (expected.kind == copley::ExpectedReply::Kind::register_value ||
          (expected.kind == copley::ExpectedReply::Kind::values && request.command[0] != 'g'))
        return with_values();
      return garbled("a CVM register value ('r n')");
    case copley::ParsedReply::Kind::error: {
      const int64_t code = parsed.values.front();
      // Through the gateway amplifier, e 32 means the addressed node did not answer on CAN.
      const Reply::Status status = (code == copley::kCanFailure && node.number != 0)
                                       ? Reply::Status::unreachable
                                       : Reply::Status::device_error;
      return Reply::of(status, fmt::format("e {}: {}", code, copley::error_text(code)), code);
    }
    case copley::ParsedReply::Kind::malformed:
      return Reply::of(Reply::Status::garbled, std::string(line));
  }
  return Reply{};
}

std::optional<std::string> CopleyFamily::pipelined_request(NodeContext& context,
                                                           const Request& request) {
  const NodeAddress& node = context.address();
  return copley::encode_command(node.number, node.axis, request.command);
}

asio::awaitable<Reply> CopleyFamily::transact(Link& link, const NodeAddress& node,
                                              const Request& request, const LinkTiming& timing) {
  // Replies carry no address: anything left over from an earlier exchange would be taken for
  // this one's reply.
  link.discard_input();
  const std::string frame = copley::encode_command(node.number, node.axis, request.command);
  if (auto ec = co_await link.send(frame))
    co_return Reply::of(Reply::Status::link_down, ec.message());
  const auto read = co_await link.read_frame(copley::frame_length, timing);
  switch (read.status) {
    case LinkRead::Status::frame:
      co_return interpret_copley_reply(node, request, read.frame);
    case LinkRead::Status::timeout:
      if (read.partial.empty()) co_return Reply::of(Reply::Status::timeout, "no reply");
      co_return Reply::of(Reply::Status::garbled, "incomplete reply '" + read.partial + "'");
    case LinkRead::Status::overflow:
      co_return Reply::of(Reply::Status::garbled, "reply longer than any Copley reply");
    case LinkRead::Status::error:
      co_return Reply::of(Reply::Status::link_down, read.error.message());
  }
  co_return Reply{};
}

Family::NodeTimingNeed CopleyFamily::node_timing_need(const NodeAddress& node,
                                                      const LinkTiming& bus) const {
  if (node.number == 0) return {};
  const auto can =
      bus.forward_timeout.count() > 0
          ? bus.forward_timeout
          : std::chrono::duration_cast<std::chrono::microseconds>(kCopleyDefaultCanTimeout);
  NodeTimingNeed need;
  need.reply_timeout = can + kCopleyForwardMargin;
  need.why = fmt::format(
      "node {} is reached over CAN: the gateway amplifier answers e 32 for an absent node only "
      "after its CAN timeout ({} ms{}), which a shorter reply timeout would not wait for",
      node.text, std::chrono::duration_cast<std::chrono::milliseconds>(can).count(),
      bus.forward_timeout.count() > 0 ? ", forward_timeout" : ", assumed: set forward_timeout");
  return need;
}

std::size_t CopleyFamily::estimate_wire_chars(const NodeAddress& node,
                                              const Request& request) const {
  const std::size_t request_chars =
      copley::encode_command(node.number, node.axis, request.command).size();
  // A typical reply: "v -2147483648\r" or "ok\r".
  return request_chars + (request.expect == Request::Expect::values ? 14 : 3);
}

}  // namespace fieldgate

namespace fieldgate {
FamilyPtr make_copley_ascii_family() {
  return std::make_shared<CopleyFamily>();
}
}  // namespace fieldgate
