#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/awaitable.hpp>
#include <boost/asio/steady_timer.hpp>

#include <functional>
#include <vector>

#include "drivers/protocol_family.hpp"
#include "gateway/process_image.hpp"
#include "mapping/model.hpp"

namespace fieldgate {

class Bus;

// Runs a model's action for a node: sends its steps through the node's bus, each confirmed
// before the next, then watches the done/failed condition on freshly polled values and keeps
// the node's action status (busy, done, error) up to date for the PLC's handshake.
class ActionRunner {
 public:
  using BusOf = std::function<Bus&(int node_index)>;

  ActionRunner(asio::any_io_executor executor, ProcessImage& image, BusOf bus_of);
  ~ActionRunner();

  // Returns once every step was acknowledged (the reply of the failing step otherwise). The
  // completion watch goes on in the background.
  asio::awaitable<Reply> start(int node_index, ModelPtr model, const ActionDef& action);
  // Called when a poll brought new values for a node.
  void node_updated(int node_index);
  void stop();

 private:
  asio::awaitable<void> watch(int node_index, ModelPtr model, const ActionDef& action,
                              uint64_t generation, SteadyTime acknowledged);
  bool refreshed_since(const NodeImage& node, const Model& model,
                       const std::string& condition_point, SteadyTime since) const;
  std::optional<bool> evaluate(const NodeImage& node, const Model& model, const Condition& c,
                               SteadyTime acknowledged) const;

  asio::any_io_executor executor_;
  ProcessImage& image_;
  BusOf bus_of_;
  std::vector<std::vector<asio::steady_timer*>> waiters_;  // per node
  bool stopping_ = false;
};

}  // namespace fieldgate
