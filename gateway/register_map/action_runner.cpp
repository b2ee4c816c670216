#include "gateway/register_map/action_runner.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/experimental/awaitable_operators.hpp>
#include <boost/asio/experimental/channel.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>

#include "gateway/bus/bus.hpp"
#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

using namespace boost::asio::experimental::awaitable_operators;

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
// How long an action that names other axes' positions waits for them to be read after the
// action before it on the node let go of the line.
constexpr auto kHeldValuePatience = std::chrono::seconds(5);
using Clock = std::chrono::steady_clock;
using ReplyChannel = asio::experimental::channel<void(boost::system::error_code, Reply)>;

// A detached submit whose reply a step picks up later. Parameters by value: the frame owns them.
asio::awaitable<void> submit_into(Bus& bus, int node_index, Request request, CommandOptions options,
                                  std::shared_ptr<ReplyChannel> out) {
  Reply reply = co_await bus.submit(node_index, std::move(request), options);
  out->try_send(boost::system::error_code{}, std::move(reply));
}

Reply reply_of(std::tuple<boost::system::error_code, Reply> received) {
  auto [ec, reply] = std::move(received);
  if (ec) return Reply::of(Reply::Status::link_down, "gateway stopping");
  return reply;
}

std::optional<int64_t> point_value(const NodeImage& node, const Model& model,
                                   const std::string& name) {
  if (name.empty()) return std::nullopt;
  for (std::size_t i = 0; i < model.points.size(); ++i)
    if (model.points[i].name == name && node.points[i].valid) return node.points[i].value;
  return std::nullopt;
}

uint16_t action_error_of(const Reply& r) {
  switch (r.status) {
    case Reply::Status::device_error:
      return static_cast<uint16_t>(r.device_code);
    case Reply::Status::unreachable:
    case Reply::Status::link_down:
      return kActionErrorUnreachable;
    case Reply::Status::timeout:
      return kActionErrorNoReply;  // sent: it may have run
    case Reply::Status::garbled:
      return kActionErrorGarbled;  // sent, and what came back was corrupted: it may have run
    default:
      return kActionErrorTimeout;
  }
}
}  // namespace

// The answer to the Modbus write that started an action, given once: early by a confirm_after
// step, otherwise when the steps are through.
struct ActionRunner::Confirmation {
  explicit Confirmation(asio::any_io_executor executor) : channel(executor, 1) {}
  void give(const Reply& reply) {
    if (given) return;
    given = true;
    channel.try_send(boost::system::error_code{}, reply);
  }
  ReplyChannel channel;
  bool given = false;
};

ActionRunner::ActionRunner(asio::any_io_executor executor, ProcessImage& image, BusOf bus_of)
    : executor_(executor), image_(image), bus_of_(std::move(bus_of)) {}

ActionRunner::~ActionRunner() {
  stop();
}

void ActionRunner::stop() {
  stopping_ = true;
  for (std::size_t i = 0; i < image_.size(); ++i)
    for (auto* t : image_.node(static_cast<int>(i)).waiters) t->cancel();
}

void ActionRunner::node_updated(int node_index) {
  for (auto* t : image_.node(node_index).waiters) t->cancel();
}

ActionState& ActionRunner::state_of(int node_index, const std::shared_ptr<ActionState>& slot) {
  return slot ? *slot : image_.node(node_index).action;
}

asio::awaitable<Reply> ActionRunner::start(int node_index, ModelPtr model_ptr,
                                           const ActionDef& action,
                                           std::shared_ptr<ActionState> slot,
                                           std::optional<ActionArguments> arguments) {
  auto& state = state_of(node_index, slot);
  const uint64_t generation = ++state.generation;
  state.status = ActionStatus::busy;
  state.code = action.code;
  state.error = 0;
  ++state.sequence;
  ActionArguments args = arguments ? std::move(*arguments)
                                   : ActionArguments{image_.node(node_index).setpoints, {}, {}};
  const bool confirms_early =
      std::any_of(action.steps.begin(), action.steps.end(),
                  [](const ActionStep& s) { return s.confirm_after.has_value(); });
  if (!confirms_early)
    co_return co_await run_steps(node_index, model_ptr, action, generation, slot, {},
                                 std::move(args));
  auto confirmation = std::make_shared<Confirmation>(executor_);
  asio::co_spawn(executor_,
                 run_in_background(node_index, std::move(model_ptr), action, generation, slot,
                                   confirmation, std::move(args)),
                 asio::detached);
  auto [ec, reply] = co_await confirmation->channel.async_receive(use_tuple);
  if (ec) co_return Reply::of(Reply::Status::link_down, "gateway stopping");
  co_return reply;
}

bool ActionRunner::takes_turn(const ActionDef& action) {
  if (action.bus_wide) return false;
  return !std::all_of(action.steps.begin(), action.steps.end(), [](const ActionStep& s) {
    return s.urgent || s.kind == ActionStep::Kind::delay;
  });
}

asio::awaitable<std::shared_ptr<HeldTurn>> ActionRunner::take_turn(int node_index) {
  co_return co_await fieldgate::take_turn(image_.node(node_index).turn);
}

asio::awaitable<void> ActionRunner::run_in_background(int node_index, ModelPtr model_ptr,
                                                      const ActionDef& action, uint64_t generation,
                                                      std::shared_ptr<ActionState> slot,
                                                      std::shared_ptr<Confirmation> confirmation,
                                                      ActionArguments arguments) {
  co_await run_steps(node_index, std::move(model_ptr), action, generation, std::move(slot),
                     confirmation, std::move(arguments));
}

asio::awaitable<bool> ActionRunner::fill_held(int node_index, const Model& model,
                                              ActionArguments& arguments, SteadyTime since) {
  auto& node = image_.node(node_index);
  const auto fresh = [&] {
    return std::all_of(arguments.hold.begin(), arguments.hold.end(), [&](const auto& h) {
      const auto& v = node.points[h.second];
      return v.valid && v.updated > since;
    });
  };
  if (!fresh()) {
    log::debug("node {}: waiting for a reading of the held points after the previous action",
               node_index);
    asio::steady_timer wake(executor_);
    node.waiters.push_back(&wake);
    const auto deadline = Clock::now() + kHeldValuePatience;
    while (!fresh() && !stopping_ && Clock::now() < deadline) {
      wake.expires_at(deadline);
      co_await wake.async_wait(use_tuple);
    }
    node.waiters.erase(std::remove(node.waiters.begin(), node.waiters.end(), &wake),
                       node.waiters.end());
    if (!fresh()) co_return false;
  }
  for (const auto& [setpoint, point] : arguments.hold)
    if (setpoint < arguments.setpoints.size() && point < model.points.size())
      arguments.setpoints[setpoint] = node.points[point].value;
  co_return true;
}

asio::awaitable<Reply> ActionRunner::submit_confirming(Bus& bus, int node_index, int number,
                                                       const Request& request,
                                                       CommandOptions options,
                                                       std::chrono::microseconds patience,
                                                       Confirmation& confirmation, uint16_t code,
                                                       std::shared_ptr<ActionState> slot) {
  auto pending = std::make_shared<ReplyChannel>(executor_, 1);
  // The patience counts from the moment the command goes on the wire, not from the queue: a
  // command still waiting behind a slow poll or a resync is not running, and a stop sent on the
  // strength of an early confirmation would reach the controller before the move it stops.
  auto sent = std::make_shared<bool>(false);
  auto sent_signal = std::make_shared<asio::steady_timer>(executor_, SteadyTime::max());
  options.on_sent = [sent, sent_signal] {
    *sent = true;
    sent_signal->cancel();
  };
  asio::co_spawn(executor_, submit_into(bus, number, request, options, pending), asio::detached);
  if (!*sent) {
    auto queued =
        co_await (pending->async_receive(use_tuple) || sent_signal->async_wait(use_tuple));
    if (queued.index() == 0) co_return reply_of(std::get<0>(std::move(queued)));
  }
  asio::steady_timer timer(executor_, patience);
  auto first = co_await (pending->async_receive(use_tuple) || timer.async_wait(use_tuple));
  if (first.index() == 0) co_return reply_of(std::get<0>(std::move(first)));
  // Still no reply: the command is on its way and running. The write is confirmed; the action
  // stays busy until the reply arrives.
  confirmation.give(Reply::of(Reply::Status::ok));
  // The line is the node's whoever started the action: the native layout sees it held too.
  auto& action = image_.node(node_index).action;
  action.holding_line = true;
  action.holding_code = code;
  if (slot) slot->holding_line = true;
  auto late = co_await pending->async_receive(use_tuple);
  action.holding_line = false;
  if (slot) slot->holding_line = false;
  co_return reply_of(std::move(late));
}

asio::awaitable<Reply> ActionRunner::run_steps(int node_index, ModelPtr model_ptr,
                                               const ActionDef& action, uint64_t generation,
                                               std::shared_ptr<ActionState> slot,
                                               std::shared_ptr<Confirmation> confirmation,
                                               ActionArguments arguments) {
  const Model& model = *model_ptr;
  auto& state = state_of(node_index, slot);
  auto& bus = bus_of_(node_index);
  const NodeImage& node = image_.node(node_index);
  const uint64_t resets = node.controller_resets;
  const std::string node_name = bus.node_config(node_index).name;
  std::shared_ptr<HeldTurn> turn = std::move(arguments.turn);
  if (!turn && takes_turn(action)) turn = co_await take_turn(node_index);
  if (state.generation != generation) {
    // A newer action of the same slot took over while this one waited for the node's turn:
    // none of its steps went out.
    if (confirmation) confirmation->give(Reply::of(Reply::Status::ok));
    co_return Reply::of(Reply::Status::ok, "superseded before it was sent");
  }
  if (!arguments.hold.empty()) {
    // Read after the previous holder of the turn let go; an action that takes no turn (a stop)
    // goes out at once with the values as they are.
    const SteadyTime since = turn ? turn->previous_release() : SteadyTime{};
    const bool filled = co_await fill_held(node_index, model, arguments, since);
    if (!filled) {
      Reply unknown = Reply::of(Reply::Status::unreachable,
                                "no reading of the held points after the previous action");
      if (state.generation == generation) {
        state.status = ActionStatus::error;
        state.error = kActionErrorUnreachable;
      }
      log::warning("node {}: action {} not sent: {}", node_name, action.name, unknown.text);
      if (confirmation) confirmation->give(unknown);
      co_return unknown;
    }
  }
  const auto& setpoints = arguments.setpoints;
  // A reload between two steps may renumber the node on its bus (a node added before it).
  const uint64_t numbering = bus.numbering();
  const auto lookup = [&](std::string_view name) -> int64_t {
    for (std::size_t i = 0; i < model.setpoints.size() && i < setpoints.size(); ++i)
      if (model.setpoints[i].name == name) return setpoints[i];
    return 0;  // unreachable: placeholders are checked against setpoints at load
  };
  Reply reply = Reply::of(Reply::Status::ok);
  for (const auto& step : action.steps) {
    if (step.kind == ActionStep::Kind::delay) {
      asio::steady_timer t(executor_, step.duration);
      co_await t.async_wait(use_tuple);
      continue;
    }
    Request request = Request::of_template(step.command, lookup, action.bus_wide);
    CommandOptions options;
    options.accept_no_reply = step.accept_no_reply;
    options.urgent = step.urgent;
    const auto number = bus.number_now(node_index, numbering, node);
    if (!number) {
      reply = Reply::of(Reply::Status::unreachable, "the node was taken off its bus by a reload");
    } else if (step.confirm_after && confirmation && !confirmation->given) {
      reply = co_await submit_confirming(bus, node_index, *number, request, options,
                                         *step.confirm_after, *confirmation, action.code, slot);
    } else {
      reply = co_await bus.submit(*number, request, options);
    }
    // A device code the step accepts (e.g. Copley's e 32 after a remote reset) is success,
    // whether the family classed it as a device error or as the node being unreachable.
    const bool coded = reply.status == Reply::Status::device_error ||
                       (reply.status == Reply::Status::unreachable && reply.device_code != 0);
    if (coded && std::find(step.accept_errors.begin(), step.accept_errors.end(),
                           reply.device_code) != step.accept_errors.end())
      reply.status = Reply::Status::ok;
    if (reply.status != Reply::Status::ok) {
      if (state.generation == generation) {
        state.status = ActionStatus::error;
        state.error = action_error_of(reply);
      }
      log::warning("node {}: action {} failed at '{}': {}", node_name, action.name, request.command,
                   reply.text.empty() ? std::string(to_string(reply.status)) : reply.text);
      if (confirmation) confirmation->give(reply);
      co_return reply;
    }
  }
  turn.reset();
  if (confirmation) confirmation->give(reply);
  if (!action.done && action.failed.empty()) {
    if (state.generation == generation) state.status = ActionStatus::done;
    co_return reply;
  }
  asio::co_spawn(executor_,
                 watch(node_index, model_ptr, action, generation, slot, Clock::now(), resets),
                 asio::detached);
  co_return reply;
}

std::optional<bool> ActionRunner::evaluate(const NodeImage& node, const Model& model,
                                           const Condition& c, SteadyTime acknowledged) const {
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    if (model.points[i].name != c.point) continue;
    const auto& v = node.points[i];
    if (!v.valid || v.updated <= acknowledged) return std::nullopt;
    const int64_t observed = c.bit ? ((v.value >> *c.bit) & 1) : v.value;
    return observed == c.equals;
  }
  return std::nullopt;
}

const Condition* ActionRunner::first_holding(const NodeImage& node, const Model& model,
                                             const std::vector<Condition>& conditions,
                                             SteadyTime acknowledged) const {
  for (const auto& c : conditions)
    if (evaluate(node, model, c, acknowledged).value_or(false)) return &c;
  return nullptr;
}

namespace {

const std::string& action_condition_point(const ActionDef& action) {
  return action.done ? action.done->point : action.failed.front().point;
}

// When a watch gives up on seeing the action's end: its condition point not read for twenty poll
// periods of its class, and never less than 30 s. A loaded machine stalls a bus for seconds, a
// line that will not go quiet is drained and reopened, and an offline node is probed again only
// every probe_interval: 15 s was seen to run out in such a recovery on a loaded CI machine.
std::optional<Clock::duration> completion_blind_after(const Model& model, const ActionDef& action) {
  const PointDef* p = model.find_point(action_condition_point(action));
  if (!p || p->poll_class.empty()) return std::nullopt;
  const PollClassDef* c = model.find_poll_class(p->poll_class);
  if (!c || c->period.count() <= 0) return std::nullopt;
  return std::max<Clock::duration>(20 * c->period, std::chrono::seconds(30));
}

SteadyTime condition_updated(const NodeImage& node, const Model& model, const ActionDef& action) {
  const std::string& name = action_condition_point(action);
  for (std::size_t i = 0; i < model.points.size(); ++i)
    if (model.points[i].name == name) return node.points[i].updated;
  return {};
}

}  // namespace

bool ActionRunner::refreshed_since(const NodeImage& node, const Model& model,
                                   const std::string& condition_point, SteadyTime since) const {
  const PointDef* p = model.find_point(condition_point);
  if (!p) return true;
  for (std::size_t i = 0; i < model.points.size(); ++i)
    if (model.points[i].poll_class == p->poll_class && model.points[i].readable() &&
        node.points[i].updated <= since)
      return false;
  return true;
}

// Holds the model so a reload cannot free the action it watches.
asio::awaitable<void> ActionRunner::watch(int node_index, ModelPtr model_ptr,
                                          const ActionDef& action, uint64_t generation,
                                          std::shared_ptr<ActionState> slot,
                                          SteadyTime acknowledged, uint64_t resets) {
  const Model& model = *model_ptr;
  asio::steady_timer wake(executor_);
  auto& list = image_.node(node_index).waiters;
  list.push_back(&wake);
  const auto deadline = acknowledged + action.timeout;
  auto& node = image_.node(node_index);
  auto& state = state_of(node_index, slot);
  std::optional<SteadyTime> settled_since;
  const auto blind_after = completion_blind_after(model, action);
  for (;;) {
    if (stopping_ || state.generation != generation) break;
    if (node.controller_resets != resets) {
      state.status = ActionStatus::error;
      state.error = kActionErrorControllerReset;
      log::warning("node {}: action {} failed: the controller reset while it ran", node_index,
                   action.name);
      break;
    }
    if (const Condition* failed = first_holding(node, model, action.failed, acknowledged)) {
      state.status = ActionStatus::error;
      state.error = kActionErrorFailedCondition;
      if (const auto code = point_value(node, model, failed->error_from); code && *code > 0)
        state.error = static_cast<uint16_t>(*code);
      break;
    }
    if (action.done && !settled_since &&
        evaluate(node, model, *action.done, acknowledged).value_or(false))
      settled_since = Clock::now();
    // Done only once every point polled with the condition's point was read again after the
    // condition held, so a PLC that reads the position on `done` sees where the axis stopped.
    if (settled_since && refreshed_since(node, model, action.done->point, *settled_since)) {
      state.status = ActionStatus::done;
      break;
    }
    if (Clock::now() >= deadline) {
      state.status = ActionStatus::error;
      state.error = kActionErrorTimeout;
      log::warning("node {}: action {} did not complete within {} ms", node_index, action.name,
                   std::chrono::duration_cast<std::chrono::milliseconds>(action.timeout).count());
      break;
    }
    // Polls that keep failing (garbled replies leave a node online) would otherwise hold the
    // action busy until its timeout, which for a long move is half an hour.
    auto wake_at = deadline;
    if (blind_after) {
      const auto last_seen = std::max(acknowledged, condition_updated(node, model, action));
      if (Clock::now() - last_seen >= *blind_after) {
        const bool offline = node.state == NodeState::offline;
        // The action's own slot (a profile axis keeps its own), checked against this
        // generation at the top of the loop with no wait since.
        state.status = ActionStatus::error;
        state.error = offline ? kActionErrorUnreachable : kActionErrorGarbled;
        log::warning(
            "node {}: action {} failed: its end cannot be seen, point '{}' not read "
            "for {} ms ({}; last error: {})",
            node_index, action.name, action_condition_point(action),
            std::chrono::duration_cast<std::chrono::milliseconds>(*blind_after).count(),
            offline ? "node offline" : "polls failing",
            node.counters.last_error_text.empty() ? "none" : node.counters.last_error_text);
        break;
      }
      wake_at = std::min(deadline, last_seen + *blind_after);
    }
    wake.expires_at(wake_at);
    co_await wake.async_wait(use_tuple);
  }
  list.erase(std::remove(list.begin(), list.end(), &wake), list.end());
}

}  // namespace fieldgate
