#include "gateway/sparkplug/command_executor.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <fmt/format.h>

namespace fieldgate::sparkplug {

namespace {

using Clock = std::chrono::steady_clock;

// Action errors after which the action may or may not have done its work.
bool outcome_unknown(uint16_t error) {
  return error == kActionErrorTimeout || error == kActionErrorNoReply ||
         error == kActionErrorGarbled;
}

}  // namespace

asio::awaitable<void> execute_command(CommandTarget target, DeviceMetric metric, Metric value,
                                      CommandReport report) {
  const auto reject = [&](std::string detail) { report({"rejected", std::move(detail), true}); };
  const auto number = integer_value(value);
  if (!number) {
    reject("the value is null or not an integer or boolean");
    co_return;
  }
  ControlWrite write{ControlWrite::Kind::point, target.node_index, metric.index, *number};
  const ActionDef* action = nullptr;
  using S = DeviceMetric::Source;
  if (metric.source == S::action) {
    if (*number != 1) {
      reject("write true to start an action");
      co_return;
    }
    const Model& model = *target.control->node_config(target.node_index).model;
    action = &model.actions.at(static_cast<std::size_t>(metric.index));
    write = {ControlWrite::Kind::action, target.node_index, 0, action->code};
  } else if (metric.source == S::setpoint) {
    write.kind = ControlWrite::Kind::setpoint;
  } else if (metric.source != S::point) {
    reject("the metric is not writable");
    co_return;
  }
  NodeImage& node = target.image->node(target.node_index);
  const ControlResult result = co_await target.control->write(write, target.policy);
  if (result.status == ControlStatus::outcome_unknown) {
    report({"unknown",
            fmt::format("sent without a valid reply, it may have run ({})", result.detail), true});
    co_return;
  }
  if (!result.ok()) {
    report({"failed", fmt::format("{}: {}", to_string(result.status), result.detail), true});
    co_return;
  }
  if (!action) {
    report({"confirmed", "acknowledged by the controller", true});
    co_return;
  }
  const uint64_t generation = node.action.generation;
  if (node.action.status != ActionStatus::busy) {
    // No completion condition, or it ended already.
    const bool done = node.action.status == ActionStatus::done;
    report({done ? "done" : "error", fmt::format("action error {}", node.action.error), true});
    co_return;
  }
  report({"confirmed", "acknowledged by the controller; under way", false});
  asio::steady_timer timer(co_await asio::this_coro::executor);
  const auto deadline = Clock::now() + action->timeout + std::chrono::seconds(2);
  for (;;) {
    if (node.action.generation != generation) {
      report({"superseded", "another action was started on the device", true});
      co_return;
    }
    if (node.action.status == ActionStatus::done) {
      report({"done", "completion seen in freshly polled values", true});
      co_return;
    }
    if (node.action.status == ActionStatus::error) {
      const uint16_t error = node.action.error;
      if (outcome_unknown(error))
        report({"unknown", fmt::format("action error 0x{:04X}: outcome not known", error), true});
      else
        report({"error", fmt::format("action error {}", error), true});
      co_return;
    }
    if (Clock::now() >= deadline) {
      report({"unknown", "no completion seen within the action's timeout", true});
      co_return;
    }
    timer.expires_after(std::chrono::milliseconds(50));
    co_await timer.async_wait(asio::as_tuple(asio::use_awaitable));
  }
}

}  // namespace fieldgate::sparkplug
