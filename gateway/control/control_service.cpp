#include "gateway/control/control_service.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "gateway/bus/bus.hpp"
#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

ControlService::ControlService(std::shared_ptr<const LoadedConfig> config, ProcessImage& image,
                               ActionRunner& actions, BusOf bus_of)
    : config_(std::move(config)), image_(image), actions_(actions), bus_of_(std::move(bus_of)) {
  for (const auto& bus : config_->gateway.buses)
    for (const auto& node : bus.nodes) nodes_.push_back(&node);
  for (std::size_t n = 0; n < nodes_.size(); ++n)
    numbering_.push_back(bus_of_(static_cast<int>(n)).numbering());
}

ControlResult ControlService::check_range(const NodeConfig& node, const std::string& name,
                                          Limits limits, int64_t value) const {
  if (!in_range(limits.type, value))
    return ControlResult::of(
        ControlStatus::out_of_range,
        fmt::format("{} = {} is out of the range of {}", name, value, to_string(limits.type)));
  // The site's limits narrow the model's, never widen them.
  if (const auto l = node.limits.find(name); l != node.limits.end()) {
    if (l->second.min && (!limits.min || *l->second.min > *limits.min)) limits.min = l->second.min;
    if (l->second.max && (!limits.max || *l->second.max < *limits.max)) limits.max = l->second.max;
  }
  if (limits.min && value < *limits.min)
    return ControlResult::of(
        ControlStatus::out_of_range,
        fmt::format("{} = {} is below its minimum {}", name, value, *limits.min));
  if (limits.max && value > *limits.max)
    return ControlResult::of(
        ControlStatus::out_of_range,
        fmt::format("{} = {} is above its maximum {}", name, value, *limits.max));
  return ControlResult::success();
}

ControlResult ControlService::check_value(int node_index, const std::string& name,
                                          int64_t value) const {
  const NodeConfig& node = node_config(node_index);
  if (const SetpointDef* s = node.model->find_setpoint(name))
    return check_range(node, name, {s->type, s->min, s->max}, value);
  if (const PointDef* p = node.model->find_point(name))
    return check_range(node, name, {p->type, p->min, p->max}, value);
  return ControlResult::of(ControlStatus::no_such_target,
                           fmt::format("the model has no point or setpoint '{}'", name));
}

bool ControlService::line_held_for(int node, const ActionDef& action) const {
  if (!image_.node(node).action.holding_line) return false;
  return !std::all_of(action.steps.begin(), action.steps.end(),
                      [](const ActionStep& s) { return s.urgent; });
}

ControlResult ControlService::check_command(int node, const ActionDef* first,
                                            const WritePolicy& policy) const {
  if (!policy.device || !policy.setpoints)
    return ControlResult::of(
        ControlStatus::writes_disabled,
        fmt::format("commands to {} are disabled here", node_config(node).name));
  if (first && line_held_for(node, *first))
    return ControlResult::of(
        ControlStatus::line_held,
        fmt::format("a running action of {} holds its line", node_config(node).name));
  return ControlResult::success();
}

ControlResult ControlService::check(const ControlWrite& w, const WritePolicy& policy) const {
  if (w.node < 0 || static_cast<std::size_t>(w.node) >= nodes_.size())
    return ControlResult::of(ControlStatus::no_such_target, fmt::format("no node {}", w.node));
  const NodeConfig& node = node_config(w.node);
  const Model& model = *node.model;
  const auto index = static_cast<std::size_t>(w.index);
  switch (w.kind) {
    case ControlWrite::Kind::setpoint: {
      if (w.index < 0 || index >= model.setpoints.size())
        return ControlResult::of(ControlStatus::no_such_target,
                                 fmt::format("{} has no setpoint {}", node.name, w.index));
      const auto& s = model.setpoints[index];
      if (auto r = check_range(node, s.name, {s.type, s.min, s.max}, w.value); !r.ok()) return r;
      if (!policy.setpoints)
        return ControlResult::of(ControlStatus::writes_disabled,
                                 fmt::format("{} is read-only here", node.name));
      return ControlResult::success();
    }
    case ControlWrite::Kind::point: {
      if (w.index < 0 || index >= model.points.size() || !model.points[index].writable())
        return ControlResult::of(ControlStatus::no_such_target,
                                 fmt::format("{} has no writable point {}", node.name, w.index));
      const auto& p = model.points[index];
      if (auto r = check_range(node, p.name, {p.type, p.min, p.max}, w.value); !r.ok()) return r;
      if (!policy.device || !policy.setpoints)
        return ControlResult::of(ControlStatus::writes_disabled,
                                 fmt::format("writes to {} are disabled here", node.name));
      if (image_.node(w.node).action.holding_line)
        return ControlResult::of(ControlStatus::line_held,
                                 fmt::format("a running action of {} holds its line", node.name));
      return ControlResult::success();
    }
    case ControlWrite::Kind::action: {
      const ActionDef* action = w.value >= 0 && w.value <= 0xffff
                                    ? model.find_action(static_cast<uint16_t>(w.value))
                                    : nullptr;
      if (!action)
        return ControlResult::of(ControlStatus::out_of_range,
                                 fmt::format("{} has no action with code {}", node.name, w.value));
      return check_command(w.node, action, policy);
    }
  }
  return ControlResult::of(ControlStatus::no_such_target, "unknown kind of write");
}

asio::awaitable<ControlResult> ControlService::apply(ControlWrite w) {
  const NodeConfig& node = node_config(w.node);
  const ModelPtr model = node.model;
  auto& image = image_.node(w.node);
  const auto index = static_cast<std::size_t>(w.index);
  switch (w.kind) {
    case ControlWrite::Kind::setpoint:
      image.setpoints[index] = w.value;
      co_return ControlResult::success();
    case ControlWrite::Kind::point: {
      const auto& p = model->points[index];
      const int64_t v = w.value;
      Request request = Request::of_template(p.write->request, [v](std::string_view) { return v; });
      Bus& bus = bus_of_(w.node);
      const auto number =
          bus.number_now(w.node, numbering_[static_cast<std::size_t>(w.node)], image);
      if (!number)
        co_return ControlResult::of(ControlStatus::unreachable,
                                    "the node was taken off its bus by a reload");
      const Reply reply = co_await bus.submit(*number, request);
      ControlResult result = control_result_of(reply);
      if (!result.ok()) {
        log::warning("node {}: write of {} = {} failed: {}", node.name, p.name, w.value,
                     result.detail);
        co_return result;
      }
      // The confirmed value until the next poll; for a write-only point, its only readback.
      store_confirmed_value(image_.node(w.node).points[index], w.value, Clock::now());
      co_return result;
    }
    case ControlWrite::Kind::action: {
      const ActionDef* action = model->find_action(static_cast<uint16_t>(w.value));
      if (!action)
        co_return ControlResult::of(ControlStatus::out_of_range,
                                    fmt::format("no action with code {}", w.value));
      std::shared_ptr<ActionState> node_register;  // the node's own action registers
      co_return co_await start_action(w.node, *action, node_register);
    }
  }
  co_return ControlResult::of(ControlStatus::no_such_target, "unknown kind of write");
}

asio::awaitable<ControlResult> ControlService::write(ControlWrite w, WritePolicy policy) {
  ControlResult checked = check(w, policy);
  if (!checked.ok()) co_return checked;
  co_return co_await apply(w);
}

asio::awaitable<ControlResult> ControlService::start_action(
    int node, const ActionDef& action, std::shared_ptr<ActionState> slot,
    std::optional<ActionArguments> arguments) {
  const ModelPtr model = node_config(node).model;
  const Reply reply =
      co_await actions_.start(node, model, action, std::move(slot), std::move(arguments));
  co_return control_result_of(reply);
}

}  // namespace fieldgate
