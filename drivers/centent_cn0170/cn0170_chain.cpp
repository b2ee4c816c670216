#include "drivers/centent_cn0170/cn0170_chain.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fieldgate::cn0170 {

namespace {

std::string unit_name(int unit) {
  return fmt::format("unit {}", unit);
}

}  // namespace

const ModelOptionSpecs& option_specs() {
  static const ModelOptionSpecs specs{
      flag_option("confirm_commands", "true",
                  "follow every command with M? and wait for the mode reply (the CN0170 "
                  "acknowledges nothing)"),
      choice_option("overflow_mode", "warning", {"warning", "rts", "leave"},
                    "what a unit in Immediate Mode does when its queue fills: send a warning, "
                    "drop RTS, or leave the unit's setting alone"),
      choice_option("overflow_command", "", {"M1\\-", "M1-", "M1\\+", "M1+"},
                    "the overflow command to send; none: M1\\- (warning) or M1\\+ (rts), "
                    "retried without the backslash if the unit rejects it"),
      flag_option("leading_cr", "true",
                  "start every transmission with a CR, so a unit that reset auto-bauds on it"),
      flag_option("autobaud_cr", "true", "send a lone CR when the link opens"),
      flag_option("discover_chain", "true", "ask .U? when the link opens"),
      choice_option("kill_target", "first_unit", {"first_unit", "every_unit"},
                    "where a kill (K) is sent: the first unit (it relays it down the chain) or "
                    "every unit"),
      flag_option("reselect_for_commands", "true", "select the unit again before every command"),
      flag_option("guard_program_mode", "true",
                  "refuse motor and I/O traffic to a unit in Program Mode (M2)"),
      flag_option("guard_position_sign", "true",
                  "refuse an absolute move whose target and the axis's last read position lie "
                  "on opposite sides of 0 (a unit comparing positions unsigned would run the "
                  "long way round its 32-bit register)"),
  };
  return specs;
}

Options parse_options(const Model& model, Diagnostics& diagnostics) {
  const auto v = check_model_options(model, "centent-cn0170", option_specs(), diagnostics);
  Options o;
  o.confirm_commands = v.flag("confirm_commands");
  o.leading_cr = v.flag("leading_cr");
  o.autobaud_cr = v.flag("autobaud_cr");
  o.discover_chain = v.flag("discover_chain");
  o.reselect_for_commands = v.flag("reselect_for_commands");
  o.guard_program_mode = v.flag("guard_program_mode");
  o.guard_position_sign = v.flag("guard_position_sign");
  const std::string& mode = v.text("overflow_mode");
  o.overflow = mode == "rts"     ? Options::Overflow::rts
               : mode == "leave" ? Options::Overflow::leave
                                 : Options::Overflow::warning;
  o.kill_target = v.text("kill_target") == "every_unit" ? Options::KillTarget::every_unit
                                                        : Options::KillTarget::first_unit;
  o.overflow_command = v.text("overflow_command");
  if (!o.overflow_command.empty() && o.overflow != Options::Overflow::leave) {
    const bool rts = o.overflow_command.find('+') != std::string::npos;
    if (rts != (o.overflow == Options::Overflow::rts))
      diagnostics.error(v.mark("overflow_command"),
                        fmt::format("model {}: option overflow_command '{}' contradicts "
                                    "overflow_mode {}",
                                    model.name, o.overflow_command, mode));
  }
  return o;
}

void Chain::link_opened() {
  selected.reset();
  for (auto& u : units) {
    u.mode = 0;
    u.set_up = false;
    u.queue_full = false;
    u.answering = false;
  }
  order.clear();
  order_known = false;
  drain_before_next = false;
  positions = {};
}

int Chain::chain_position(int unit) const {
  if (!order_known) return 0;
  const auto it = std::find(order.begin(), order.end(), unit);
  return it == order.end() ? 0 : static_cast<int>(it - order.begin()) + 1;
}

void Chain::absorb(const Message& m) {
  auto& u = units[static_cast<std::size_t>(m.unit)];
  switch (m.kind) {
    case MessageKind::position:
    case MessageKind::velocity:
    case MessageKind::acceleration:
    case MessageKind::profile:
    case MessageKind::ratio:
    case MessageKind::io:
    case MessageKind::aux:
    case MessageKind::analog:
    case MessageKind::mode:
    case MessageKind::time:
    case MessageKind::date:
      if (pay(m.unit, m.key)) return;
      break;
    default:
      break;
  }
  switch (m.kind) {
    case MessageKind::autobaud: {
      // U<n> answers the first CR after a reset: the unit lost its selection, clock and queues,
      // and selects itself or nobody; nothing else on the chain can be trusted to be selected.
      const auto subject = static_cast<std::size_t>(m.subject);
      auto& reset = units[subject];
      ++reset.counters.resets;
      reset.reset_unreported = true;
      owed[subject].clear();  // its queues are gone: nothing it owed will come
      ++reset.counters.unsolicited;
      reset.set_up = false;
      reset.mode = 0;
      reset.queue_full = false;
      positions[subject] = {};
      forget_selection();
      log(4, fmt::format("{} reset (unsolicited 'U{}'): selection forgotten, the unit's clock "
                         "and queues are lost",
                         unit_name(m.subject), m.subject));
      return;
    }
    case MessageKind::queue_full:
      if (!u.queue_full)
        log(4, fmt::format("{}: queue nearly full (Q*); instructions are refused until *Q",
                           unit_name(m.unit)));
      u.queue_full = true;
      ++u.counters.overflow_warnings;
      break;
    case MessageKind::queue_empty:
      if (u.queue_full) log(5, fmt::format("{}: queue empty again (*Q)", unit_name(m.unit)));
      u.queue_full = false;
      break;
    case MessageKind::position_trigger:
      ++(m.key == "X" ? u.counters.x_done : u.counters.y_done);
      break;
    case MessageKind::velocity_trigger:
      ++(m.key == "X" ? u.counters.x_vmax : u.counters.y_vmax);
      break;
    case MessageKind::reject:
      ++u.counters.rejects;
      log(4, fmt::format("{} rejected \"{}\" outside an exchange", unit_name(m.unit), m.text));
      break;
    case MessageKind::mode:
      u.mode = static_cast<int>(m.values.front());
      ++stray_lines;
      return;
    case MessageKind::unit_list:
    case MessageKind::time:
    case MessageKind::date:
      // Output of .U?, T? or D? stored in a program that runs in M3.
      break;
    case MessageKind::blank:
      return;
    default:
      // A reply nobody waits for: late, after its exchange timed out.
      ++stray_lines;
      return;
  }
  ++u.counters.unsolicited;
}

namespace {

Reply refusal(int64_t code, std::string text) {
  return Reply::of(Reply::Status::device_error, std::move(text), code);
}

void select(Chain& chain, Plan& plan, int unit) {
  plan.bytes += encode_select(unit);
  plan.selects = true;
  chain.selected = unit;
  ++chain.selections;
  ++chain.units[static_cast<std::size_t>(unit)].counters.selections;
}

Query mode_query() {
  return *classify_query("M?");
}

// An absolute move that crosses 0 in the signed view (README "Absolute moves and the sign").
std::optional<Reply> position_sign_refusal(const Chain& chain, int unit,
                                           const std::string& instruction) {
  for (const auto& t : absolute_targets(instruction)) {
    const auto& known = chain.positions[static_cast<std::size_t>(unit)][t.axis == 'X' ? 0 : 1];
    const int64_t from = known ? static_cast<int32_t>(*known) : 0;
    if ((t.raw < 0) == (from < 0)) continue;
    return refusal(
        kInvalidValue,
        fmt::format("'{}': absolute {} move of unit {} to {} from {}{} (1/1024 step) crosses 0: "
                    "the CN0170's positions are unsigned ('positive only'), so the unit may run "
                    "the long way round its 4,194,304-step register instead; move relative, or "
                    "declare the position (XP=) first",
                    instruction, t.axis, unit, t.raw, from,
                    known ? "" : " (assumed: not polled yet)"));
  }
  return std::nullopt;
}

}  // namespace

Plan plan_request(Chain& chain, const Options& options, int unit, const Request& request) {
  Plan plan;
  plan.read = request.expect == Request::Expect::values;
  std::string error;
  const auto normalised = normalise_request(request.command, error);
  if (!normalised) {
    plan.refused = refusal(kInvalidValue, error);
    return plan;
  }
  const auto instructions = split_instructions(*normalised);
  if (instructions.empty()) {
    plan.refused = refusal(kInvalidValue, "empty request");
    return plan;
  }
  const auto& state = chain.units[static_cast<std::size_t>(unit)];
  bool assignment = false;
  bool moves_queue = false;  // an instruction that takes a place in the Immediate Queue
  bool mode_change = false;
  bool only_mode_queries = true;
  for (const auto& instruction : instructions) {
    const auto kind = classify_instruction(instruction);
    if (kind == InstructionKind::query) {
      plan.expected.push_back(*classify_query(instruction));
      if (plan.expected.back().kind != MessageKind::mode) only_mode_queries = false;
      continue;
    }
    if (plan.read) {
      plan.refused = refusal(kInvalidValue, fmt::format("'{}' is not a query", instruction));
      return plan;
    }
    switch (kind) {
      case InstructionKind::unit_command:
        plan.refused = refusal(kInvalidValue,
                               fmt::format("'{}': the family selects units itself", instruction));
        return plan;
      case InstructionKind::unit_assignment:
        assignment = true;
        break;
      case InstructionKind::mode_program:
        plan.refused = refusal(kInvalidValue,
                               "M2 from Immediate Mode erases the stored program; the "
                               "gateway never sends it");
        return plan;
      case InstructionKind::mode_immediate:
      case InstructionKind::mode_operate:
        mode_change = true;
        break;
      case InstructionKind::kill:
      case InstructionKind::quit:
      case InstructionKind::halt:
        break;
      default:
        moves_queue = true;
        only_mode_queries = false;
        if (options.guard_position_sign)
          if (auto refused = position_sign_refusal(chain, unit, instruction)) {
            plan.refused = std::move(refused);
            return plan;
          }
        break;
    }
  }
  plan.program_mode_ok = mode_change;
  if (options.guard_program_mode && state.mode == 2 && !mode_change && !only_mode_queries) {
    plan.refused = refusal(kProgramMode, fmt::format("unit {} is in Program Mode (M2): the "
                                                     "request would be stored in its program",
                                                     unit));
    return plan;
  }
  // Queries still go to a unit in M3 (a discarded one times out; no value is made up), and so
  // do H, Q and K (whose confirmation then says it is unconfirmed).
  if (options.guard_program_mode && state.mode == 3 && !mode_change && moves_queue) {
    plan.refused = refusal(kOperateMode, fmt::format("unit {} is in Operate Mode (M3): the "
                                                     "request may be discarded, not executed; "
                                                     "send M1 (immediate_mode) first",
                                                     unit));
    return plan;
  }
  if (state.queue_full && moves_queue) {
    plan.refused = refusal(kQueueFull, fmt::format("unit {} warned that its queue is nearly "
                                                   "full (Q*); waiting for *Q",
                                                   unit));
    return plan;
  }
  if (options.leading_cr) {
    plan.bytes += '\r';
    plan.leading_cr = true;
  }
  const bool command = !plan.read;
  if (!chain.selected || *chain.selected != unit || (command && options.reselect_for_commands) ||
      assignment)
    select(chain, plan, unit);
  plan.bytes += *normalised;
  plan.bytes += '\r';
  if (command && options.confirm_commands) {
    plan.bytes += "M?\r";
    plan.expected.push_back(mode_query());
    plan.confirmation = true;
  }
  if (assignment) {
    // Numbers changed: which unit is selected, and the chain order, are unknown now.
    chain.forget_selection();
    chain.order_known = false;
    chain.drain_before_next = true;
    if (plan.confirmation) {
      // The unit we would ask may have a new number; don't wait for it.
      plan.bytes.resize(plan.bytes.size() - 3);
      plan.expected.pop_back();
      plan.confirmation = false;
    }
  }
  return plan;
}

Plan plan_kill(Chain& chain, const Options& options, int unit, const std::vector<int>& configured) {
  Plan plan;
  std::vector<int> targets;
  if (options.kill_target == Options::KillTarget::first_unit && chain.order_known &&
      !chain.order.empty()) {
    targets.push_back(chain.order.front());
  } else {
    targets = configured;
    if (chain.order_known)
      for (int u : chain.order)
        if (std::find(targets.begin(), targets.end(), u) == targets.end()) targets.push_back(u);
    if (targets.empty()) targets.push_back(unit);
  }
  plan.bytes += '\r';
  plan.leading_cr = true;
  for (int t : targets) {
    select(chain, plan, t);
    // In M2 a K would be stored, not obeyed; M1 does not clear the program (§7.2).
    if (chain.units[static_cast<std::size_t>(t)].mode == 2) plan.bytes += "M1\r";
    plan.bytes += "K\r";
  }
  plan.bytes += "M?\r";
  plan.expected.push_back(mode_query());
  plan.confirmation = true;
  plan.program_mode_ok = true;
  plan.reply_unit = targets.back();
  return plan;
}

void Chain::owe(int unit, const std::vector<std::string>& keys,
                std::chrono::steady_clock::time_point now) {
  if (keys.empty()) return;
  auto& debts = owed[static_cast<std::size_t>(unit)];
  // A debt added while one is open keeps its age, so a unit that never pays is written off.
  if (debts.empty()) owed_since[static_cast<std::size_t>(unit)] = now;
  debts.insert(debts.end(), keys.begin(), keys.end());
}

bool Chain::pay(int unit, const std::string& key) {
  auto& debts = owed[static_cast<std::size_t>(unit)];
  const auto it = std::find(debts.begin(), debts.end(), key);
  if (it == debts.end()) return false;
  // Owed replies before it that did not come were lost.
  debts.erase(debts.begin(), it + 1);
  ++late_replies;
  return true;
}

void Chain::expire_owed(std::chrono::steady_clock::time_point now,
                        std::chrono::steady_clock::duration window) {
  for (std::size_t u = 0; u < owed.size(); ++u) {
    if (owed[u].empty() || now - owed_since[u] <= window) continue;
    log(6, fmt::format("unit {}: gave up waiting for {} late repl{}", u, owed[u].size(),
                       owed[u].size() == 1 ? "y" : "ies"));
    owed[u].clear();
  }
}

Exchange::Exchange(Chain& chain, int unit, Plan plan, std::string what)
    : chain_(chain),
      unit_(plan.reply_unit.value_or(unit)),
      plan_(std::move(plan)),
      what_(std::move(what)) {
  was_answering_ = chain_.units[static_cast<std::size_t>(unit_)].answering;
}

void Exchange::owe_rest(std::size_t from) {
  for (std::size_t i = from; i < plan_.expected.size(); ++i) owes_.push_back(plan_.expected[i].key);
}

bool Exchange::finish(Reply::Status status, std::string text, int64_t code) {
  reply_ = Reply::of(status, std::move(text), code);
  finished_ = true;
  return true;
}

bool Exchange::finish_ok() {
  auto& state = chain_.units[static_cast<std::size_t>(unit_)];
  state.answering = true;
  if (plan_.confirmation && confirmed_mode_ == 2 && !plan_.program_mode_ok)
    return finish(Reply::Status::device_error,
                  fmt::format("unit {} is in Program Mode (M2): '{}' was stored in its program, "
                              "not executed",
                              unit_, what_),
                  kStoredInProgram);
  if (plan_.confirmation && confirmed_mode_ == 3 && !plan_.program_mode_ok)
    return finish(Reply::Status::device_error,
                  fmt::format("unit {} is in Operate Mode (M3): '{}' is not confirmed (a unit "
                              "in M3 may discard the host's instructions); send M1 first",
                              unit_, what_),
                  kOperateMode);
  reply_ = Reply::of(Reply::Status::ok);
  if (plan_.read) {
    reply_.values = values_;
    if (saw_position_) reply_.values.push_back(motion_);
  }
  finished_ = true;
  return true;
}

void Exchange::lost() {
  chain_.forget_selection();
  chain_.drain_before_next = true;
  chain_.units[static_cast<std::size_t>(unit_)].answering = false;
}

bool Exchange::on_line(std::string_view line) {
  const Message m = parse_message(line);
  switch (m.kind) {
    case MessageKind::blank:
      return false;
    case MessageKind::unknown:
      ++chain_.stray_lines;
      if (was_answering_ || next_ > 0) owe_rest(next_);
      lost();
      return finish(Reply::Status::garbled,
                    fmt::format("unreadable line '{}' while waiting for unit {}'s reply to '{}'",
                                m.text, unit_, what_));
    case MessageKind::autobaud: {
      chain_.absorb(m);
      const int pos_reset = chain_.chain_position(m.subject);
      const int pos_target = chain_.chain_position(unit_);
      // Without a leading CR, a unit at or before the target on the chain swallowed the request
      // while it waited for its auto-baud CR. With one, the unit auto-bauded on that CR and the
      // rest went on (into the unit itself, if it selected itself: its reply will show that).
      if (!plan_.leading_cr &&
          (m.subject == unit_ || (pos_reset > 0 && pos_target > 0 && pos_reset <= pos_target))) {
        lost();
        return finish(Reply::Status::garbled,
                      fmt::format("unit {} reset (U{}) during the request '{}' for unit {}; the "
                                  "request was lost and the selection is forgotten",
                                  m.subject, m.subject, what_, unit_));
      }
      reset_seen_ = m.subject;
      return false;
    }
    case MessageKind::reject:
      if (m.unit != unit_) {
        chain_.absorb(m);
        return false;
      }
      if (!chain_.owed[static_cast<std::size_t>(unit_)].empty()) {
        // It may reject an earlier request whose replies are still owed, or this one.
        ++chain_.units[static_cast<std::size_t>(unit_)].counters.rejects;
        owe_rest(next_);
        lost();
        return finish(Reply::Status::garbled,
                      fmt::format("unit {} rejected \"{}\" while replies to an earlier request "
                                  "were still owed: which request it rejects is unknown",
                                  unit_, m.text));
      }
      ++chain_.units[static_cast<std::size_t>(unit_)].counters.rejects;
      chain_.units[static_cast<std::size_t>(unit_)].answering = true;
      // Replies to the rest of the request may still follow; they must not meet the next one.
      chain_.drain_before_next = true;
      owe_rest(next_);
      return finish(Reply::Status::device_error,
                    fmt::format("unit {} rejected \"{}\" (syntax error; the string was ignored)",
                                unit_, m.text),
                    kRejected);
    case MessageKind::queue_full:
    case MessageKind::queue_empty:
    case MessageKind::position_trigger:
    case MessageKind::velocity_trigger:
      chain_.absorb(m);
      return false;
    default:
      break;
  }
  if (next_ >= plan_.expected.size()) {
    chain_.absorb(m);
    return false;
  }
  const Query& expected = plan_.expected[next_];
  const bool matches = m.kind == expected.kind && m.key == expected.key;
  if (!matches) {
    // Program output (time, date, [Un]) or a late reply to an exchange that timed out.
    chain_.absorb(m);
    return false;
  }
  if (m.unit != unit_) {
    ++chain_.stray_lines;
    // After an explicit .Un only the selected unit can have answered: this one is late.
    if (plan_.selects) return false;
    // Otherwise our request went to the wrong unit: one that reset selected itself.
    lost();
    return finish(Reply::Status::garbled,
                  fmt::format("unit {} answered '{}' meant for unit {} (it trapped the request: "
                              "a reset or a duplicate unit number); selection forgotten",
                              m.unit, what_, unit_));
  }
  const auto debt_since = chain_.owed_since[static_cast<std::size_t>(unit_)];
  if (chain_.pay(unit_, m.key)) {
    if (!paid_debt_since_) paid_debt_since_ = debt_since;
    // The late answer to an earlier request with the same key: ours comes after it.
    chain_.absorb(m);
    return false;
  }
  if (m.kind == MessageKind::mode)
    chain_.units[static_cast<std::size_t>(unit_)].mode = static_cast<int>(m.values.front());
  const bool is_confirmation = plan_.confirmation && next_ + 1 == plan_.expected.size();
  if (is_confirmation) {
    confirmed_mode_ = static_cast<int>(m.values.front());
  } else {
    values_.insert(values_.end(), m.values.begin(), m.values.end());
    if (m.kind == MessageKind::position) {
      saw_position_ = true;
      motion_ |= m.values[1];
      chain_.positions[static_cast<std::size_t>(unit_)][m.key.front() == 'X' ? 0 : 1] =
          static_cast<uint32_t>(m.values[0]);
    }
  }
  ++next_;
  if (next_ == plan_.expected.size()) return finish_ok();
  return false;
}

Reply Exchange::on_timeout(std::string_view partial) {
  // A reply cut off inside the line: its rest comes as a fragment no key can match, never as
  // the whole reply, so it is not owed (those after it still are).
  const bool cut_reply =
      next_ < plan_.expected.size() && starts_reply(partial, unit_, plan_.expected[next_]);
  if (was_answering_ || next_ > 0 || !partial.empty()) owe_rest(cut_reply ? next_ + 1 : next_);
  lost();
  if (!partial.empty())
    finish(Reply::Status::garbled,
           fmt::format("incomplete reply '{}' from unit {} to '{}'", partial, unit_, what_));
  else if (next_ > 0)
    finish(Reply::Status::garbled, fmt::format("unit {} sent {} of the {} replies to '{}'", unit_,
                                               next_, plan_.expected.size(), what_));
  else if (reset_seen_)
    finish(Reply::Status::garbled,
           fmt::format("no reply from unit {} to '{}' after unit {} reset (U{})", unit_, what_,
                       *reset_seen_, *reset_seen_));
  else
    finish(Reply::Status::timeout, fmt::format("no reply from unit {} to '{}'", unit_, what_));
  return reply_;
}

Reply Exchange::on_overflow(std::string_view partial) {
  lost();
  finish(Reply::Status::garbled,
         fmt::format("line of {} bytes without a terminator while waiting for unit {}",
                     partial.size(), unit_));
  return reply_;
}

Reply Exchange::on_too_many_lines() {
  lost();
  finish(Reply::Status::garbled,
         fmt::format("too many unrelated lines while waiting for unit {}'s reply to '{}'", unit_,
                     what_));
  return reply_;
}

Reply Exchange::on_link_error(std::string text) {
  chain_.forget_selection();
  finish(Reply::Status::link_down, std::move(text));
  return reply_;
}

std::vector<int64_t> counters_of(const Chain& chain, int unit) {
  const auto& u = chain.units[static_cast<std::size_t>(unit)];
  std::vector<int64_t> v(kCounterFields);
  const auto c = [](uint64_t n) { return static_cast<int64_t>(n & 0xffffffffu); };
  v[kResets] = c(u.counters.resets);
  v[kRejects] = c(u.counters.rejects);
  v[kOverflowWarnings] = c(u.counters.overflow_warnings);
  v[kQueueFullNow] = u.queue_full ? 1 : 0;
  v[kXMoveDone] = c(u.counters.x_done);
  v[kYMoveDone] = c(u.counters.y_done);
  v[kXMaxVelocity] = c(u.counters.x_vmax);
  v[kYMaxVelocity] = c(u.counters.y_vmax);
  v[kUnsolicited] = c(u.counters.unsolicited);
  v[kSelections] = c(u.counters.selections);
  v[kChainPosition] = chain.chain_position(unit);
  v[kMode] = u.mode;
  return v;
}

}  // namespace fieldgate::cn0170
