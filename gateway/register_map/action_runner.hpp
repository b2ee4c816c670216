#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/awaitable.hpp>
#include <boost/asio/steady_timer.hpp>

#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "drivers/protocol_family.hpp"
#include "gateway/image/process_image.hpp"
#include "mapping/model.hpp"

namespace fieldgate {

class Bus;
struct CommandOptions;

// Runs a model's action for a node: sends its steps through the node's bus, each confirmed
// before the next, then watches the done/failed conditions on freshly polled values and keeps
// the node's action status (busy, done, error) up to date for the PLC's handshake.
//
// A step with confirm_after answers the Modbus write early: once it has been on the wire that long
// without a reply (a move acknowledged only at its end); time in the bus's queue does not count.
// The rest of the action then runs in the background and ends in done or error like any other.
class ActionRunner {
 public:
  using BusOf = std::function<Bus&(int node_index)>;

  ActionRunner(asio::any_io_executor executor, ProcessImage& image, BusOf bus_of);
  ~ActionRunner();

  // Returns once every step was acknowledged (the reply of the failing step otherwise), or once
  // a confirm_after step has waited that long for its reply. The completion watch goes on in the
  // background. The action's status goes to `slot` if given (a profile axis keeps its own, so
  // two axes of one node do not supersede each other), else to the node's action register.
  //
  // The steps run with `arguments` (by default the node's setpoints as they are now) and in the
  // node's turn: no other action's step for the node goes between them. An action of urgent
  // steps only (a stop byte) or for the whole bus takes no turn.
  asio::awaitable<Reply> start(int node_index, ModelPtr model, const ActionDef& action,
                               std::shared_ptr<ActionState> slot = nullptr,
                               std::optional<ActionArguments> arguments = std::nullopt);
  // Takes the node's turn for a caller that sends more than one action's steps (point writes
  // before the action) in it.
  asio::awaitable<std::shared_ptr<HeldTurn>> take_turn(int node_index);
  // Whether an action waits for the node's turn.
  static bool takes_turn(const ActionDef& action);
  // Called when a poll brought new values for a node.
  void node_updated(int node_index);
  void stop();

 private:
  struct Confirmation;
  ActionState& state_of(int node_index, const std::shared_ptr<ActionState>& slot);
  asio::awaitable<Reply> run_steps(int node_index, ModelPtr model, const ActionDef& action,
                                   uint64_t generation, std::shared_ptr<ActionState> slot,
                                   std::shared_ptr<Confirmation> confirmation,
                                   ActionArguments arguments);
  // `number`: the node's number on the bus now (node_index, unless a reload renumbered it).
  asio::awaitable<Reply> submit_confirming(Bus& bus, int node_index, int number,
                                           const Request& request, CommandOptions options,
                                           std::chrono::microseconds patience,
                                           Confirmation& confirmation, uint16_t code,
                                           std::shared_ptr<ActionState> slot);
  asio::awaitable<void> run_in_background(int node_index, ModelPtr model, const ActionDef& action,
                                          uint64_t generation, std::shared_ptr<ActionState> slot,
                                          std::shared_ptr<Confirmation> confirmation,
                                          ActionArguments arguments);
  // Fills the held setpoints from values polled after `since`; false if none came in time.
  asio::awaitable<bool> fill_held(int node_index, const Model& model, ActionArguments& arguments,
                                  SteadyTime since);
  asio::awaitable<void> watch(int node_index, ModelPtr model, const ActionDef& action,
                              uint64_t generation, std::shared_ptr<ActionState> slot,
                              SteadyTime acknowledged, uint64_t resets);
  bool refreshed_since(const NodeImage& node, const Model& model,
                       const std::string& condition_point, SteadyTime since) const;
  std::optional<bool> evaluate(const NodeImage& node, const Model& model, const Condition& c,
                               SteadyTime acknowledged) const;
  // The first of `conditions` that holds on values read after `acknowledged`, if any.
  const Condition* first_holding(const NodeImage& node, const Model& model,
                                 const std::vector<Condition>& conditions,
                                 SteadyTime acknowledged) const;

  asio::any_io_executor executor_;
  ProcessImage& image_;
  BusOf bus_of_;
  bool stopping_ = false;
};

}  // namespace fieldgate
