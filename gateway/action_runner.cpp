#include "gateway/action_runner.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>

#include "gateway/bus.hpp"
#include "gateway/log.hpp"

namespace fieldgate {

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
using Clock = std::chrono::steady_clock;

uint16_t action_error_of(const Reply& r) {
  switch (r.status) {
    case Reply::Status::device_error:
      return static_cast<uint16_t>(r.device_code);
    case Reply::Status::unreachable:
    case Reply::Status::link_down:
      return kActionErrorUnreachable;
    default:
      return kActionErrorTimeout;
  }
}
}  // namespace

ActionRunner::ActionRunner(asio::any_io_executor executor, ProcessImage& image, BusOf bus_of)
    : executor_(executor), image_(image), bus_of_(std::move(bus_of)), waiters_(image.size()) {}

ActionRunner::~ActionRunner() {
  stop();
}

void ActionRunner::stop() {
  stopping_ = true;
  for (auto& list : waiters_)
    for (auto* t : list) t->cancel();
}

void ActionRunner::node_updated(int node_index) {
  for (auto* t : waiters_[static_cast<std::size_t>(node_index)]) t->cancel();
}

asio::awaitable<Reply> ActionRunner::start(int node_index, ModelPtr model_ptr,
                                           const ActionDef& action) {
  const Model& model = *model_ptr;
  auto& state = image_.node(node_index).action;
  const uint64_t generation = ++state.generation;
  state.status = ActionStatus::busy;
  state.code = action.code;
  state.error = 0;
  ++state.sequence;
  auto& bus = bus_of_(node_index);
  const auto& setpoints = image_.node(node_index).setpoints;
  const auto lookup = [&](std::string_view name) -> int64_t {
    for (std::size_t i = 0; i < model.setpoints.size(); ++i)
      if (model.setpoints[i].name == name) return setpoints[i];
    return 0;  // unreachable: placeholders are checked against setpoints at load
  };
  Reply reply;
  reply.status = Reply::Status::ok;
  for (const auto& step : action.steps) {
    if (step.kind == ActionStep::Kind::delay) {
      asio::steady_timer t(executor_, step.duration);
      co_await t.async_wait(use_tuple);
      continue;
    }
    Request request{step.command.render(lookup), Request::Expect::ack, NumberFormat::decimal,
                    action.bus_wide};
    reply =
        co_await bus.submit(node_index, request, CommandOptions{step.accept_no_reply, step.urgent});
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
      log::warning("node {}: action {} failed at '{}': {}", bus.node_config(node_index).name,
                   action.name, request.command,
                   reply.text.empty() ? std::string(to_string(reply.status)) : reply.text);
      co_return reply;
    }
  }
  if (!action.done && !action.failed) {
    if (state.generation == generation) state.status = ActionStatus::done;
    co_return reply;
  }
  asio::co_spawn(executor_, watch(node_index, model_ptr, action, generation, Clock::now()),
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
                                          SteadyTime acknowledged) {
  const Model& model = *model_ptr;
  asio::steady_timer wake(executor_);
  auto& list = waiters_[static_cast<std::size_t>(node_index)];
  list.push_back(&wake);
  const auto deadline = acknowledged + action.timeout;
  auto& node = image_.node(node_index);
  std::optional<SteadyTime> settled_since;
  for (;;) {
    if (stopping_ || node.action.generation != generation) break;
    if (action.failed && evaluate(node, model, *action.failed, acknowledged).value_or(false)) {
      node.action.status = ActionStatus::error;
      node.action.error = kActionErrorFailedCondition;
      break;
    }
    if (action.done && !settled_since &&
        evaluate(node, model, *action.done, acknowledged).value_or(false))
      settled_since = Clock::now();
    // Done only once every point polled with the condition's point was read again after the
    // condition held, so a PLC that reads the position on `done` sees where the axis stopped.
    if (settled_since && refreshed_since(node, model, action.done->point, *settled_since)) {
      node.action.status = ActionStatus::done;
      break;
    }
    if (Clock::now() >= deadline) {
      node.action.status = ActionStatus::error;
      node.action.error = kActionErrorTimeout;
      log::warning("node {}: action {} did not complete within {} ms", node_index, action.name,
                   std::chrono::duration_cast<std::chrono::milliseconds>(action.timeout).count());
      break;
    }
    wake.expires_at(deadline);
    co_await wake.async_wait(use_tuple);
  }
  list.erase(std::remove(list.begin(), list.end(), &wake), list.end());
}

}  // namespace fieldgate
