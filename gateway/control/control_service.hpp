#pragma once

#include <boost/asio/awaitable.hpp>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gateway/config/config_loader.hpp"
#include "gateway/control/control_result.hpp"
#include "gateway/image/process_image.hpp"
#include "gateway/register_map/action_runner.hpp"

namespace fieldgate {

class Bus;

// What a front door lets its clients change. A Modbus listener's read-only units and tables
// allow nothing; `writes_enabled: false` (monitor-only commissioning) still allows setpoints,
// which stay in the gateway until an action passes them on.
struct WritePolicy {
  bool setpoints = true;
  bool device = true;  // point writes and actions
};

// One write or command of a PLC, as every front door names it: a node by the gateway's node
// number, a point or setpoint by its index in the node's model, an action by its code.
struct ControlWrite {
  enum class Kind { point, setpoint, action };
  Kind kind = Kind::point;
  int node = 0;
  int index = 0;      // point or setpoint index; unused for an action
  int64_t value = 0;  // the value, or the action's code
};

// The rules every write meets, whichever door it came through: the type's range, the model's and
// the site's limits, the door's policy, a line held by a running action, confirmation by the
// controller, and the action runner. The front doors translate requests into ControlWrites and
// the results back into their own codes; none keeps a copy of these rules.
class ControlService {
 public:
  using BusOf = std::function<Bus&(int node_index)>;

  ControlService(std::shared_ptr<const LoadedConfig> config, ProcessImage& image,
                 ActionRunner& actions, BusOf bus_of);

  // Everything short of the device, without effect, in this order: target, range and limits,
  // policy, held line. A request of several writes checks them all before any runs.
  ControlResult check(const ControlWrite& write, const WritePolicy& policy) const;
  // Carries out a checked write: a setpoint is stored, a point written and confirmed by the
  // controller (its value then reads back until the next poll), an action started.
  asio::awaitable<ControlResult> apply(ControlWrite write);
  // check, then apply.
  asio::awaitable<ControlResult> write(ControlWrite write, WritePolicy policy);

  // For commands made of several writes (the axis profile): a value for the point or setpoint
  // named `name` of the node's model, against its type, the model's and the site's limits.
  ControlResult check_value(int node, const std::string& name, int64_t value) const;
  // Whether a command whose first action is `first` (none: a command the gateway answers on its
  // own) may start now: the policy, then the held line.
  ControlResult check_command(int node, const ActionDef* first, const WritePolicy& policy) const;
  // Whether `action` must wait for the node's line, held by a running action's step (only an
  // action made of urgent steps, a stop byte, gets past it).
  bool line_held_for(int node, const ActionDef& action) const;
  // Starts an action whose status goes to `slot` (a profile axis keeps its own).
  // `arguments`: what its steps send (by default the node's setpoints as they are now).
  asio::awaitable<ControlResult> start_action(
      int node, const ActionDef& action, std::shared_ptr<ActionState> slot,
      std::optional<ActionArguments> arguments = std::nullopt);

  const NodeConfig& node_config(int node) const {
    return *nodes_.at(static_cast<std::size_t>(node));
  }
  std::size_t node_count() const { return nodes_.size(); }

 private:
  struct Limits {
    ValueType type = ValueType::int32;
    std::optional<int64_t> min, max;
  };
  ControlResult check_range(const NodeConfig& node, const std::string& name, Limits limits,
                            int64_t value) const;

  std::shared_ptr<const LoadedConfig> config_;
  ProcessImage& image_;
  ActionRunner& actions_;
  BusOf bus_of_;
  std::vector<const NodeConfig*> nodes_;  // by the gateway's node number
  // Each node's bus's numbering when this configuration was put in force: a write still under
  // way after a later reload renumbered the bus finds its node again (Bus::number_of).
  std::vector<uint64_t> numbering_;
};

}  // namespace fieldgate
