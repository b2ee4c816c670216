#include "gateway/sparkplug/command_executor.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <fmt/format.h>

#include <span>

namespace fieldgate::sparkplug {

namespace {

using Clock = std::chrono::steady_clock;

const RegisterEntry* entry_for(const UnitMap& unit, const DeviceMetric& metric) {
  using S = DeviceMetric::Source;
  for (const auto& e : unit.tables[static_cast<std::size_t>(Table::holding_registers)]) {
    if (!e.writable) continue;
    if (metric.source == S::point && e.kind == RegisterEntry::Kind::point &&
        e.index == metric.index)
      return &e;
    if (metric.source == S::setpoint && e.kind == RegisterEntry::Kind::setpoint &&
        e.index == metric.index)
      return &e;
    if (metric.source == S::action && e.kind == RegisterEntry::Kind::action_command) return &e;
  }
  return nullptr;
}

// Action errors after which the action may or may not have done its work.
bool outcome_unknown(uint16_t error) {
  return error == kActionErrorTimeout || error == kActionErrorNoReply ||
         error == kActionErrorGarbled;
}

}  // namespace

asio::awaitable<void> execute_command(CommandTarget target, DeviceMetric metric, Metric value,
                                      CommandReport report) {
  const auto reject = [&](std::string detail) { report({"rejected", std::move(detail), true}); };
  const UnitMap* unit = target.config->map_of(target.listener).unit(target.unit_id);
  if (!unit) {
    reject("the device has no register map");
    co_return;
  }
  const auto number = integer_value(value);
  if (!number) {
    reject("the value is null or not an integer or boolean");
    co_return;
  }
  int64_t written = *number;
  const ActionDef* action = nullptr;
  if (metric.source == DeviceMetric::Source::action) {
    if (written != 1) {
      reject("write true to start an action");
      co_return;
    }
    action = &unit->model->actions.at(static_cast<std::size_t>(metric.index));
    written = action->code;
  }
  const RegisterEntry* entry = entry_for(*unit, metric);
  if (!entry) {
    reject("the metric has no writable register");
    co_return;
  }
  if (!in_range(entry->type, written)) {
    report({"failed", fmt::format("{} is out of the range of {}", written, to_string(entry->type)),
            true});
    co_return;
  }
  const std::vector<uint16_t> words =
      to_registers(entry->type, written, target.config->map_of(target.listener).word_order());
  const std::span<const uint16_t> registers(words);
  NodeImage& node = target.image->node(target.node_index);
  const uint64_t unknown_before = node.counters.unknown_writes;
  const modbus::WriteResult result =
      co_await target.handler->write_registers(target.unit_id, entry->address, registers);
  if (!result.ok()) {
    const auto ex = result.exception();
    if (ex == modbus::ExceptionCode::gateway_target_failed &&
        node.counters.unknown_writes != unknown_before) {
      report({"unknown", "sent without a valid reply: it may have run", true});
      co_return;
    }
    std::string detail =
        fmt::format("exception 0x{:02X} ({})", static_cast<int>(ex), modbus::to_string(ex));
    if (ex == modbus::ExceptionCode::server_device_failure &&
        !node.counters.last_error_text.empty())
      detail += ": " + node.counters.last_error_text;
    report({"failed", detail, true});
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
