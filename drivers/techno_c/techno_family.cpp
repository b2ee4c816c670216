#include "drivers/techno_c/techno_family.hpp"

#include "drivers/printable_bytes.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <utility>

namespace fieldgate {

using techno::Command;
using techno::CommandKind;
using techno::Handshake;

namespace {

using std::chrono::duration_cast;
using std::chrono::microseconds;

// Long waits are read in slices so a stop sent meanwhile ends them promptly.
constexpr microseconds kWaitSlice{std::chrono::milliseconds(20)};

microseconds seconds_to_us(double seconds) {
  return microseconds(static_cast<int64_t>(std::llround(seconds * 1e6)));
}

Reply link_down(const std::error_code& ec) {
  return Reply::of(Reply::Status::link_down, ec.message());
}

Reply device_error(char code) {
  return Reply::of(Reply::Status::device_error, techno::describe_error(code),
                   static_cast<unsigned char>(code));
}

Reply from_parsed(const techno::ParsedReply& parsed, std::string_view frame) {
  switch (parsed.kind) {
    case techno::ParsedReply::Kind::ok: {
      Reply r = Reply::of(Reply::Status::ok);
      r.values = parsed.values;
      return r;
    }
    case techno::ParsedReply::Kind::error:
      return device_error(parsed.code);
    case techno::ParsedReply::Kind::malformed:
      return Reply::of(Reply::Status::garbled,
                       parsed.problem.empty() ? std::string(frame) : parsed.problem);
  }
  return Reply{};
}

}  // namespace

Reply interpret_techno_reply(const Request& request, std::string_view frame, int fitted_axes) {
  const Command c = techno::classify(request.command);
  if (c.kind == CommandKind::position)
    return from_parsed(techno::parse_positions(frame, fitted_axes), frame);
  if (c.kind == CommandKind::peek) return from_parsed(techno::parse_peek(frame), frame);
  Reply r = from_parsed(techno::parse_handshake(frame), frame);
  if (r.status == Reply::Status::ok && request.expect == Request::Expect::values)
    return Reply::of(Reply::Status::garbled,
                     "'" + request.command + "' answers only a handshake, no data");
  return r;
}

std::optional<NodeAddress> TechnoFamily::parse_address(std::string_view text,
                                                       std::string& error) const {
  const auto device = techno::parse_device(text, error);
  if (!device) return std::nullopt;
  return NodeAddress::numbered(*device);
}

void TechnoFamily::validate_model(const Model& model, Diagnostics& diagnostics) const {
  const techno::Profile p = techno::read_profile(model, diagnostics);
  techno::check_model(model, p, diagnostics);
}

NodeContextPtr TechnoFamily::bind_node(const NodeAddress& node, const Model& model) {
  // Errors were reported by validate_model; a model with errors never runs.
  Diagnostics reported;
  auto bound = std::make_shared<BoundNode>(node, techno::read_profile(model, reported));
  std::erase_if(bound_, [](const auto& b) { return b.expired(); });
  bound_.push_back(bound);
  profile_.reset();
  return bound;
}

const techno::Profile& TechnoFamily::profile() {
  if (!profile_) {
    std::vector<techno::Profile> profiles;
    for (const auto& weak : bound_) {
      const auto b = weak.lock();
      if (!b) continue;
      const bool seen = std::any_of(profiles.begin(), profiles.end(),
                                    [&](const auto& p) { return p.model == b->profile.model; });
      if (!seen) profiles.push_back(b->profile);
    }
    profile_ = techno::merge_profiles(profiles);
  }
  return *profile_;
}

TechnoFamily::BoundNode& TechnoFamily::active(NodeContext& node) {
  // Every context this family's transact_node() receives is one its bind_node() made.
  auto& bound = static_cast<BoundNode&>(node);
  bound.active = true;
  return bound;
}

techno::MotionContext TechnoFamily::motion_context(const BoundNode& node) {
  const auto& p = node.profile;
  const auto& state = node.state;
  techno::MotionContext c;
  c.axes = p.axes;
  c.plane = state.plane;
  c.acceleration = p.acceleration;
  c.position = state.position;
  c.travel = p.travel;
  for (std::size_t i = 0; i < 3; ++i) c.home_speed[i] = state.home_speed[i].value_or(p.home_speed);
  return c;
}

asio::awaitable<void> TechnoFamily::on_link_open(Link&, const LinkTiming&) {
  // The controller may have been power-cycled or moved by hand while the port was closed.
  // seen_defined is kept: it is evidence about the controller, not about the port, and a `4`
  // after a reopen must still read as a lost definition (a motion is then not repeated).
  for (const auto& weak : bound_)
    if (const auto b = weak.lock()) {
      b->state = NodeState{};
      b->active = false;
    }
  co_return;
}

microseconds TechnoFamily::reply_budget(const NodeAddress& node, std::string_view command,
                                        const LinkTiming& timing) {
  return reply_budget(active(context_of(node)), command, timing);
}

microseconds TechnoFamily::reply_budget(BoundNode& node, std::string_view command,
                                        const LinkTiming& timing) {
  const auto& p = node.profile;
  auto& state = node.state;
  const Command c = techno::classify(command);
  microseconds budget = timing.reply_timeout;
  const auto now = Clock::now();
  // A controller busy with a lower-case motion may answer only when it has finished [inf].
  if (state.motion_pending && now < state.motion_deadline)
    budget = std::max(
        budget, duration_cast<microseconds>(state.motion_deadline - now) + timing.reply_timeout);
  if (c.handshake != Handshake::at_end) return budget;
  if (c.kind == CommandKind::start_program) return budget + p.program_timeout;
  const auto values = techno::parse_values(c.values).value_or(std::vector<int64_t>{});
  const auto estimate = techno::estimate_motion(c, values, motion_context(node));
  if (!estimate) return budget + p.program_timeout;
  return budget + seconds_to_us(estimate->seconds * p.timeout_factor) + p.timeout_margin;
}

asio::awaitable<TechnoFamily::Waited> TechnoFamily::wait_reply(Link& link,
                                                               const FrameSplitter& splitter,
                                                               microseconds budget,
                                                               const LinkTiming& timing) {
  const uint64_t interrupts_at_start = interrupts_;
  auto deadline = Clock::now() + budget;
  Waited waited;
  for (;;) {
    if (!waited.interrupted && interrupts_ != interrupts_at_start) {
      // After a stop a handshake, if any comes, comes once the axes have ramped down.
      waited.interrupted = true;
      deadline = std::min(deadline, Clock::now() + profile().stop_settle);
    }
    const auto now = Clock::now();
    if (now >= deadline) {
      waited.read = LinkRead{};
      co_return waited;
    }
    const LinkTiming slice{std::min(duration_cast<microseconds>(deadline - now), kWaitSlice),
                           timing.byte_timeout};
    LinkRead read = co_await link.read_frame(splitter, slice);
    if (read.status == LinkRead::Status::timeout && read.partial.empty()) continue;
    // A stop may have gone out while this read was under way (its answer can be the reply).
    waited.interrupted = waited.interrupted || interrupts_ != interrupts_at_start;
    waited.read = std::move(read);
    co_return waited;
  }
}

void TechnoFamily::after_interrupt(CommandKind kind) {
  ++interrupts_;
  last_interrupt_ = kind == CommandKind::stop ? techno::kStopByte : techno::kResetByte;
  const auto& p = profile();
  const auto now = Clock::now();
  // A stop ramps down from at most the top speed; a reset halts at once. Either way the axes are
  // no longer where the family expected them.
  const auto ramp = kind == CommandKind::stop
                        ? seconds_to_us(static_cast<double>(techno::kMaxSpeed) / p.acceleration)
                        : microseconds(0);
  for (const auto& weak : bound_) {
    const auto b = weak.lock();
    if (!b || !b->active) continue;
    auto& state = b->state;
    state.position = {};
    state.motion_pending = true;
    state.motion_estimated_end = now + ramp;
    state.motion_deadline = now + ramp + p.stop_settle;
    state.expected_end = {};
    state.expects_target = false;
    state.moved = false;
    state.last_change = now;
    state.motion_error = 0;  // the stop's ramp is what the next polls report on
    state.error_after_reply = 0;
  }
}

asio::awaitable<Reply> TechnoFamily::send_raw(Link& link, CommandKind kind) {
  const auto& p = profile();
  // Never split a command another coroutine is writing; a command line is a few ms at most.
  for (int i = 0; writing_ && i < 2000; ++i) co_await link.pause(microseconds(100));
  urgent_writing_ = true;
  const std::string bytes = techno::encode_command(
      0, kind == CommandKind::stop ? techno::kStopCommand : techno::kResetCommand, p.stop_bytes);
  const auto ec = co_await link.send(bytes);
  urgent_writing_ = false;
  if (ec) co_return link_down(ec);
  after_interrupt(kind);
  co_return Reply::of(Reply::Status::ok);
}

asio::awaitable<Reply> TechnoFamily::send_urgent(Link& link, const NodeAddress&,
                                                 const Request& request) {
  const Command c = techno::classify(request.command);
  if (c.kind != CommandKind::stop && c.kind != CommandKind::reset)
    co_return Reply::of(Reply::Status::device_error,
                        fmt::format("techno-c sends only {} and {} past a held line, not '{}'",
                                    techno::kStopCommand, techno::kResetCommand, request.command));
  co_return co_await send_raw(link, c.kind);
}

asio::awaitable<Reply> TechnoFamily::transact_node(Link& link, NodeContext& context,
                                                   const Request& request,
                                                   const LinkTiming& timing) {
  const Command c = techno::classify(request.command);
  if (c.kind == CommandKind::stop || c.kind == CommandKind::reset)
    co_return co_await send_raw(link, c.kind);
  if (request.bus_wide)
    co_return Reply::of(Reply::Status::device_error,
                        "techno-c has no broadcast address for '" + request.command + "'");
  BoundNode& bound = active(context);
  const NodeAddress& node = bound.address();
  const auto& p = bound.profile;
  auto& state = bound.state;
  if (p.init_on_connect && !state.initialised && c.kind != CommandKind::specify_axes) {
    const Request init{std::to_string(p.axes), Request::Expect::ack, NumberFormat::decimal};
    Reply r = co_await exchange(link, bound, init, timing);
    if (r.status != Reply::Status::ok) {
      r.text = fmt::format("initialising with '{}' (init_on_connect): {}", init.command, r.text);
      co_return r;
    }
  }
  Reply reply = co_await exchange(link, bound, request, timing);
  if (!(p.init_when_undefined && reply.status == Reply::Status::device_error &&
        reply.device_code == '4' && c.kind != CommandKind::specify_axes)) {
    co_await await_motion_position(link, bound, request, reply, timing);
    co_return reply;
  }
  // The controller powered up (p.69: the axes definition comes before any other operation).
  const bool lost_definition = bound.seen_defined;
  const Request init{std::to_string(p.axes), Request::Expect::ack, NumberFormat::decimal};
  const Reply defined = co_await exchange(link, bound, init, timing);
  if (defined.status != Reply::Status::ok) {
    reply.text += fmt::format("; sending the axes definition '{}' failed: {}", init.command,
                              defined.text.empty() ? to_string(defined.status) : defined.text);
    co_return reply;
  }
  link.note(fmt::format(
      "techno-c device {}: '{}' answered 4 (axes not defined){}; sent the axes "
      "definition '{}' (this clears the controller's program memory)",
      node.number, request.command,
      lost_definition ? ", the controller lost its definition (power cycle?)" : " at first contact",
      init.command));
  reply.controller_reset = lost_definition;
  if (lost_definition && techno::is_motion(c.kind)) {
    // Its positions restarted from 0 with the power: a motion would go somewhere else.
    reply.text += "; the axes are defined again, but positions were lost: home before moving";
    co_return reply;
  }
  Reply again = co_await exchange(link, bound, request, timing);
  co_await await_motion_position(link, bound, request, again, timing);
  again.controller_reset = lost_definition;
  co_return again;
}

// A lower-case move or home answers at its start. A controller that answers queries during a
// motion answers the `P` sent right after it at once; one that keeps a line arriving during a
// motion in its input buffer (p.73, Stop: "the buffered command will start running") answers it
// when the motion has ended [both readings]. Waiting for that reply here keeps the step, and
// with the model's confirm_after the action's held line, busy for as long as the axis runs under
// the second reading: the axis reads as moving from the acknowledge on (the polls queue behind
// it and could not tell), and STOP still goes out past it.
asio::awaitable<void> TechnoFamily::await_motion_position(Link& link, BoundNode& bound,
                                                          const Request& request, Reply& reply,
                                                          const LinkTiming& timing) {
  const NodeAddress& node = bound.address();
  const Command c = techno::classify(request.command);
  const bool move_or_home = c.kind == CommandKind::move_absolute ||
                            c.kind == CommandKind::move_relative || c.kind == CommandKind::home;
  if (reply.status != Reply::Status::ok || c.handshake != Handshake::at_start || !move_or_home)
    co_return;
  const uint64_t interrupts_at_start = interrupts_;
  const Request query{"P", Request::Expect::values, NumberFormat::hex24};
  const Reply position = co_await exchange(link, bound, query, timing);
  if (interrupts_ != interrupts_at_start) {
    // It was acknowledged, but a stop or reset ended it before the axes came to rest.
    reply = device_error(last_interrupt_);
    reply.text = fmt::format("'{}' ended by {} while it ran", request.command,
                             last_interrupt_ == techno::kStopByte ? "stop (0xFF)" : "reset (0xFE)");
    co_return;
  }
  // The motion runs (it was acknowledged); the polls report on it from here.
  if (position.status != Reply::Status::ok)
    link.note(
        fmt::format("techno-c device {}: '{}' acknowledged, the position query after it "
                    "failed ({}): the polls follow the motion",
                    node.number, request.command,
                    position.text.empty() ? to_string(position.status) : position.text));
}

asio::awaitable<void> TechnoFamily::collect_motion_error(Link& link, NodeState& state,
                                                         const LinkTiming& timing) {
  const LinkTiming quick{microseconds(std::llround(link.char_time_us() * 2)) + microseconds(500),
                         timing.byte_timeout};
  for (int i = 0; i < 8; ++i) {
    const LinkRead read = co_await link.read_frame(techno::handshake_frame, quick);
    if (read.status != LinkRead::Status::frame) co_return;
    const char ch = read.frame.front();
    if (ch != techno::kAck && techno::is_error_code(ch) && ch != '\r') {
      state.motion_error = static_cast<unsigned char>(ch);
      link.note(
          fmt::format("techno-c: the controller reported {} during a motion it had "
                      "acknowledged",
                      techno::describe_error(ch)));
    }
  }
}

asio::awaitable<void> TechnoFamily::resync(Link& link, const LinkTiming& timing) {
  // No reply carries an address: a late answer to a timed-out request would be taken as the
  // answer to the next one. Wait until the line has been quiet for a whole reply timeout.
  const auto guard = timing.reply_timeout + microseconds(std::llround(link.char_time_us() * 10));
  const auto any = [](std::string_view buf) { return buf.size(); };
  std::size_t drained = 0;
  for (int i = 0; i < 20; ++i) {
    const LinkRead read = co_await link.read_frame(any, LinkTiming{guard, guard});
    if (read.status != LinkRead::Status::frame) {
      drained += read.partial.size();
      if (read.partial.empty()) break;
      continue;
    }
    drained += read.frame.size();
  }
  if (drained > 0)
    link.note(fmt::format("techno-c: {} late byte(s) drained after a failed exchange", drained));
  resync_ = false;
}

asio::awaitable<LinkResync> TechnoFamily::resync_after_failure(Link& link,
                                                               const LinkTiming& timing) {
  LinkResync done = co_await ProtocolFamily::resync_after_failure(link, timing);
  if (done.quiet) resync_ = false;
  co_return done;
}

asio::awaitable<Reply> TechnoFamily::exchange(Link& link, BoundNode& bound, const Request& request,
                                              const LinkTiming& timing) {
  const NodeAddress& node = bound.address();
  const Command c = techno::classify(request.command);
  const auto values = techno::parse_values(c.values).value_or(std::vector<int64_t>{});
  const microseconds budget = reply_budget(bound, request.command, timing);
  if (resync_) co_await resync(link, timing);
  if (bound.state.motion_pending) {
    if (const auto e = std::exchange(bound.state.error_after_reply, 0))
      bound.state.motion_error = e;
    co_await collect_motion_error(link, bound.state, timing);
  }
  // Replies carry no address: anything left from an earlier exchange would be taken for this one.
  link.discard_input();
  for (int i = 0; urgent_writing_ && i < 2000; ++i) co_await link.pause(microseconds(100));
  writing_ = true;
  const auto ec = co_await link.send(techno::encode_command(node.number, request.command));
  writing_ = false;
  if (ec) co_return link_down(ec);
  const auto sent_at = Clock::now();

  const auto mode = bound.profile.position_reply;
  FrameSplitter splitter = techno::handshake_frame;
  if (c.kind == CommandKind::position)
    splitter = [mode](std::string_view buf) { return techno::position_frame(buf, mode); };
  else if (c.kind == CommandKind::peek)
    splitter = techno::peek_frame;
  Waited waited = co_await wait_reply(link, splitter, budget, timing);

  Reply reply;
  switch (waited.read.status) {
    case LinkRead::Status::frame:
      reply = interpret_techno_reply(request, waited.read.frame, bound.profile.fitted_axes);
      if (reply.status == Reply::Status::garbled && c.kind == CommandKind::position)
        take_leading_motion_error(bound, request, waited.read.frame, reply);
      if (c.kind != CommandKind::position && c.kind != CommandKind::peek)
        co_await check_single_handshake(link, c, reply, timing);
      else
        co_await take_optional_terminator(link, bound.state, waited.read.frame, reply, timing);
      break;
    case LinkRead::Status::timeout:
      if (!waited.read.partial.empty()) {
        // Queries may end without a terminator: the idle gap ends them (digest §5).
        reply = interpret_techno_reply(request, waited.read.partial, bound.profile.fitted_axes);
      } else if (waited.interrupted) {
        reply = device_error(last_interrupt_);
      } else {
        reply = Reply::of(Reply::Status::timeout,
                          fmt::format("no handshake to '{}' within {:.1f} s", request.command,
                                      static_cast<double>(budget.count()) / 1e6));
        if (c.kind == CommandKind::home)
          reply.text += " (a homing run without mechanics never answers)";
        if (c.handshake == Handshake::at_end && bound.profile.stop_on_timeout) {
          // Free the controller from whatever holds it; the manual asks for STOP twice.
          const Reply stopped = co_await send_raw(link, CommandKind::stop);
          reply.text += stopped.status == Reply::Status::ok ? "; sent stop" : "; stop failed";
        }
      }
      break;
    case LinkRead::Status::overflow:
      reply = Reply::of(Reply::Status::garbled, "reply longer than any C-series reply");
      break;
    case LinkRead::Status::error:
      reply = link_down(waited.read.error);
      break;
  }
  if (waited.interrupted && reply.status == Reply::Status::ok && techno::is_motion(c.kind) &&
      c.handshake == Handshake::at_end)
    reply = device_error(last_interrupt_);  // it answered, but the motion did not run to its end
  if (reply.status == Reply::Status::device_error &&
      (reply.device_code == static_cast<unsigned char>(techno::kStopByte) ||
       reply.device_code == static_cast<unsigned char>(techno::kResetByte)))
    reply.text = fmt::format("'{}' ended by {} before its handshake", request.command,
                             reply.device_code == static_cast<unsigned char>(techno::kStopByte)
                                 ? "stop (0xFF)"
                                 : "reset (0xFE)");
  if (reply.status == Reply::Status::timeout || reply.status == Reply::Status::garbled)
    resync_ = true;
  auto& state = bound.state;
  // No reply takes longer than the reply timeout but one the controller held back until the
  // running motion (or a stop's ramp) ended.
  const bool answered_after_motion = c.kind == CommandKind::position &&
                                     reply.status == Reply::Status::ok && state.motion_pending &&
                                     Clock::now() - sent_at > timing.reply_timeout;
  if (c.kind == CommandKind::position && reply.status == Reply::Status::ok &&
      state.motion_pending) {
    // Answered at once with the axes still on their way: the positions changed since the last
    // reply and the motion has a while to go.
    const bool running_on =
        Clock::now() + timing.reply_timeout < state.motion_estimated_end && state.last_reported &&
        reply.values.size() >= 3 &&
        *state.last_reported !=
            std::array<int64_t, 3>{reply.values[0], reply.values[1], reply.values[2]};
    std::optional<bool> deferred;
    if (answered_after_motion)
      deferred = true;
    else if (running_on && !state.queries_deferred)
      deferred = false;
    if (deferred && deferred != state.queries_deferred) {
      state.queries_deferred = deferred;
      if (*deferred)
        link.note(
            fmt::format("techno-c device {}: 'P' during a motion was answered only when "
                        "the motion had ended (a buffered line, p.73): motions count as "
                        "running until that reply",
                        node.number));
      else
        link.note(fmt::format("techno-c device {}: 'P' is answered during a motion", node.number));
    }
  }
  after_reply(bound, c, values, reply, answered_after_motion);
  if (reply.status == Reply::Status::ok) bound.seen_defined = true;
  co_return reply;
}

void TechnoFamily::take_leading_motion_error(BoundNode& node, const Request& request,
                                             std::string_view frame, Reply& reply) {
  // The error that ended a lower-case motion, sent just before this query's answer.
  NodeState& state = node.state;
  if (!state.motion_pending || frame.size() < 2) return;
  const char first = frame.front();
  if (first == techno::kAck || first == '\r' || !techno::is_error_code(first)) return;
  Reply rest = interpret_techno_reply(request, frame.substr(1), node.profile.fitted_axes);
  if (rest.status != Reply::Status::ok) return;
  state.motion_error = static_cast<unsigned char>(first);
  reply = std::move(rest);
}

// A query's reply ended by its digit count may still be followed by a CR (or CR LF): the
// manual leaves that open (README). Every reading's trailing bytes are read here, until the byte
// gap, so a late CR is never taken for the next request's answer. While a lower-case motion
// runs, one error character after them is that motion ending (a limit hit just after the
// controller answered); anything else is garbled.
asio::awaitable<void> TechnoFamily::take_optional_terminator(Link& link, NodeState& state,
                                                             std::string_view frame, Reply& reply,
                                                             const LinkTiming& timing) {
  if (frame.empty() || frame.back() == '\n') co_return;
  std::string extra;
  for (;;) {
    const LinkRead next = co_await link.read_frame(
        techno::handshake_frame, LinkTiming{timing.byte_timeout, timing.byte_timeout});
    if (next.status != LinkRead::Status::frame) break;
    extra += next.frame;
    if (extra.back() == '\n') break;
  }
  const std::string_view allowed = frame.back() == '\r' ? "\n" : "\r\n";
  const auto terminator_only = [&](std::string_view bytes) {
    return bytes.empty() || bytes == allowed || (allowed.size() == 2 && bytes == "\r");
  };
  if (terminator_only(extra)) co_return;
  if (const char last = extra.back();
      state.motion_pending && last != techno::kAck && last != '\r' && last != '\n' &&
      techno::is_error_code(last) &&
      terminator_only(std::string_view(extra).substr(0, extra.size() - 1))) {
    state.error_after_reply = static_cast<unsigned char>(last);
    link.note(
        fmt::format("techno-c: the controller reported {} right after answering a query "
                    "during a motion it had acknowledged",
                    techno::describe_error(last)));
    co_return;
  }
  reply = Reply::of(
      Reply::Status::garbled,
      fmt::format("reply '{}' followed by '{}'", printable_bytes(frame), printable_bytes(extra)));
}

asio::awaitable<void> TechnoFamily::check_single_handshake(Link& link, const Command& c,
                                                           Reply& reply, const LinkTiming& timing) {
  // One character answers a command. More after it means the line carried something else (a
  // late position reply, another request's answer): the character cannot be trusted.
  const LinkRead more = co_await link.read_frame(
      techno::handshake_frame, LinkTiming{timing.byte_timeout, timing.byte_timeout});
  if (more.status != LinkRead::Status::frame) co_return;
  std::string extra = more.frame;
  for (;;) {
    const LinkRead next = co_await link.read_frame(
        techno::handshake_frame, LinkTiming{timing.byte_timeout, timing.byte_timeout});
    if (next.status != LinkRead::Status::frame) break;
    extra += next.frame;
  }
  if (extra.find_first_not_of("\r\n") == std::string::npos) co_return;  // a CR/LF after it
  const bool acked_motion = reply.status == Reply::Status::ok && c.handshake == Handshake::at_start;
  if (acked_motion && extra.size() == 1 && techno::is_error_code(extra.front())) {
    // `0` at the start, then the error that stopped the motion at once.
    pending_error_ = static_cast<unsigned char>(extra.front());
    co_return;
  }
  reply = Reply::of(Reply::Status::garbled,
                    fmt::format("one handshake character expected, more followed ({} bytes): a "
                                "late or foreign reply",
                                extra.size() + 1));
}

void TechnoFamily::after_reply(BoundNode& node, const Command& c,
                               const std::vector<int64_t>& values, Reply& reply,
                               bool answered_after_motion) {
  const auto& p = node.profile;
  auto& state = node.state;
  const auto now = Clock::now();
  if (reply.status == Reply::Status::device_error && reply.device_code == '4') {
    // "Axis not defined": the controller was power-cycled; its settings are back to defaults.
    state = NodeState{};
    return;
  }
  if (reply.status != Reply::Status::ok) return;
  switch (c.kind) {
    case CommandKind::specify_axes:
      state = NodeState{};
      state.initialised = true;
      return;
    case CommandKind::position: {
      const std::array<int64_t, 3> xyz{reply.values[0], reply.values[1], reply.values[2]};
      const int64_t moving = in_motion(node, xyz, answered_after_motion);
      state.last_reported = xyz;
      for (std::size_t i = 0; i < 3; ++i) state.position[i] = xyz[i];
      reply.values.resize(3);
      reply.values.push_back(moving);
      for (std::size_t i = 0; i < 3; ++i)
        reply.values.push_back(p.steps_per_unit
                                   ? std::llround(static_cast<double>(xyz[i]) /
                                                  (*p.steps_per_unit)[i] / p.unit_resolution)
                                   : 0);
      reply.values.push_back(state.motion_error != 0 ? 1 : 0);
      reply.values.push_back(state.motion_error);
      return;
    }
    case CommandKind::zero:
      if (!values.empty())
        for (std::size_t i = 0; i < 3; ++i)
          if (values[0] & (int64_t{1} << i)) state.position[i] = 0;
      return;
    case CommandKind::home_speed: {
      std::size_t next = 0;
      for (std::size_t i = 0; i < 3 && next < values.size(); ++i)
        if (p.axes & (1 << i)) state.home_speed[i] = static_cast<double>(values[next++]);
      return;
    }
    case CommandKind::plane:
      if (!values.empty()) state.plane = static_cast<int>(values[0]);
      return;
    default:
      break;
  }
  if (!techno::is_motion(c.kind)) return;
  // A new motion: an error reported with its acknowledge (check_single_handshake) is its own.
  state.motion_error = std::exchange(pending_error_, 0);
  const auto estimate = techno::estimate_motion(c, values, motion_context(node));
  state.position = estimate ? estimate->end_position : std::array<std::optional<int64_t>, 3>{};
  if (c.handshake == Handshake::at_end) {
    // The handshake came at the end: the axes are at rest where the command put them.
    state.motion_pending = false;
    state.last_reported.reset();
    return;
  }
  // Acknowledged at the start: the motion runs on with the line free.
  const double seconds =
      c.kind == CommandKind::start_program ? 0.5 : (estimate ? estimate->seconds : 0.5);
  const auto limit = c.kind == CommandKind::start_program
                         ? p.program_timeout
                         : seconds_to_us(seconds * p.timeout_factor) + p.timeout_margin;
  state.motion_pending = true;
  state.motion_estimated_end = now + seconds_to_us(seconds);
  state.motion_deadline = now + limit;
  state.expected_end = estimate ? estimate->end_position : std::array<std::optional<int64_t>, 3>{};
  state.expects_target =
      c.kind == CommandKind::move_absolute || c.kind == CommandKind::move_relative;
  state.moved = false;
  state.last_change = now;
}

// 1 while a lower-case motion (or a stop's ramp) may still move axes. The motion is over when
// the polled positions stand still: at the commanded end (once they moved, or once the estimated
// time is up), or anywhere after moving for motion_settle. The estimate is only an upper bound,
// so a motion is not reported running for the worst case of an unknown start or a full travel.
// at_rest: the controller answered only once the motion had ended.
int64_t TechnoFamily::in_motion(BoundNode& node, const std::array<int64_t, 3>& xyz, bool at_rest) {
  auto& state = node.state;
  if (!state.motion_pending) return 0;
  const auto now = Clock::now();
  const bool changed = state.last_reported && *state.last_reported != xyz;
  if (changed) {
    state.moved = true;
    state.last_change = now;
  }
  const bool end_known = std::any_of(state.expected_end.begin(), state.expected_end.end(),
                                     [](const auto& e) { return e.has_value(); });
  bool at_end = end_known;
  for (std::size_t i = 0; i < 3; ++i)
    if (state.expected_end[i] && *state.expected_end[i] != xyz[i]) at_end = false;
  const bool still = at_rest || (state.last_reported && !changed);
  const bool estimate_passed = at_rest || now >= state.motion_estimated_end;
  const bool settled = state.moved && now - state.last_change >= node.profile.motion_settle;
  bool over = state.motion_error != 0 || now >= state.motion_deadline;
  if (still && at_end && (state.moved || estimate_passed)) over = true;
  if (still && (settled || estimate_passed)) {
    over = true;
    // A move that rests elsewhere than it was sent to did not reach its target.
    if (state.expects_target && end_known && !at_end && state.motion_error == 0)
      state.motion_error = techno::kShortOfTarget;
  }
  if (!over) return 1;
  state.motion_pending = false;
  return 0;
}

std::size_t TechnoFamily::estimate_wire_chars(const NodeAddress& node,
                                              const Request& request) const {
  const Command c = techno::classify(request.command);
  const std::size_t out = techno::encode_command(node.number, request.command).size();
  if (c.kind == CommandKind::position) return out + techno::kPositionDigits + 2;
  if (c.kind == CommandKind::peek) return out + 3;
  return out + 1;
}

FamilyPtr make_techno_c_family() {
  return std::make_shared<TechnoFamily>();
}

}  // namespace fieldgate
