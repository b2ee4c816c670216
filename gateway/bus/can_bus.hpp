#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/awaitable.hpp>
#include <boost/asio/steady_timer.hpp>

#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "drivers/canopen/canopen_request.hpp"
#include "drivers/canopen/node_points.hpp"
#include "drivers/canopen/node_requests.hpp"
#include "drivers/canopen/node_supervision.hpp"
#include "drivers/canopen/sdo_channel.hpp"
#include "drivers/canopen/tpdo_freshness.hpp"
#include "drivers/frame_family.hpp"
#include "drivers/transport/socketcan_transport.hpp"
#include "gateway/bus/bus.hpp"
#include "gateway/bus/pending_command.hpp"
#include "gateway/bus/poll_plan.hpp"
#include "gateway/bus/retained_configs.hpp"
#include "gateway/bus/wire_trace.hpp"
#include "gateway/config/gateway_config.hpp"
#include "gateway/image/process_image.hpp"

namespace fieldgate {

// One CAN interface with CANopen nodes. Unlike a serial line, transfers of different nodes
// overlap: each node has its own worker coroutine with its own command queue (ahead of its
// polls) and SDO client, so one SDO transfer is in flight per node while all nodes share the
// wire. One reader coroutine takes every frame off the socket and hands it on: SDO responses
// to the node's client, heartbeats to the consumer (online/offline, NMT state, boot-up), EMCY
// to the node's diagnostics and TPDOs straight into the process image. The bus reopens the
// interface with back-off when it goes down or away.
class CanBus final : public Bus, public FramePort, public std::enable_shared_from_this<CanBus> {
 public:
  // Must be owned by a shared_ptr (run() keeps it alive for its workers). Without a channel
  // the bus opens SocketCAN on config.transport.can_interface; tests pass an in-memory one.
  CanBus(asio::any_io_executor executor, std::shared_ptr<const void> config_owner,
         const BusConfig& config, int first_node_index, NodeUpdated on_update,
         std::unique_ptr<CanChannel> channel = nullptr);
  ~CanBus() override;

  asio::awaitable<void> run() override;
  void stop() override;
  asio::awaitable<Reply> submit(int node_index, Request request,
                                CommandOptions options = {}) override;

  const BusConfig& config() const override { return *config_; }
  const BusCounters& counters() const override { return counters_; }
  const CanCounters* can_counters() const override { return &can_counters_; }
  WireTrace& trace() override { return trace_; }
  const NodeConfig& node_config(int node_index) const override;
  std::vector<std::shared_ptr<NodeImage>> node_images() const override;
  void rebind(int first_node_index, NodeUpdated on_update) override;
  // In place when the bus's own part of the configuration (all but `nodes:`) is unchanged and
  // it keeps the same nodes, in the same order, as the same devices: a node's poll periods,
  // limits, setpoints, unit or listener. A node added or taken away rebuilds the bus (the
  // socket's receive filter names every node's COB-IDs).
  bool reconfigure(std::shared_ptr<const void> config_owner, const BusConfig& config,
                   int first_node_index, NodeUpdated on_update) override;
  int first_node_index() const override { return first_node_index_; }

  // The port the nodes' transfers use.
  asio::awaitable<bool> send(const CanFrame& frame, std::string_view outcome = {}) override;
  bool up() const override { return !stopping_ && link_up_; }

  // What the bus consumed from a node, for diagnostics and tests.
  using Liveness = canopen::Liveness;
  using NodeStatus = canopen::NodeStatus;
  NodeStatus node_status(int node_index) const;

 private:
  struct NodeRuntime;

  asio::awaitable<void> read_loop();
  asio::awaitable<void> node_worker(NodeRuntime& n);
  asio::awaitable<void> heartbeat_supervisor();
  // True when the time came, false when the timer was cancelled (woken).
  asio::awaitable<bool> sleep_until(asio::steady_timer& timer, SteadyTime when);

  // One poll item per object and period (points that share an object share its upload), and
  // each node's polled points.
  void plan_polls();
  void trace_frame(const CanFrame& frame, TraceDirection direction, SteadyTime at,
                   std::string_view outcome);
  asio::awaitable<void> run_poll(NodeRuntime& n, std::size_t item_index, SteadyTime now);

  void dispatch(const CanFrame& frame, SteadyTime now);
  void on_error_frame(const CanFrame& frame, SteadyTime now);
  void on_tpdo(NodeRuntime& n, const CanFrame& frame, SteadyTime now);
  void refresh_local_points(NodeRuntime& n, SteadyTime now);

  void record(NodeRuntime& n, const Reply& reply, SteadyTime sent, SteadyTime at);
  void set_state(NodeRuntime& n, NodeState state, std::string_view why);
  void link_failed(std::error_code ec);
  void fail_commands(std::string_view why);
  void wake_all();
  void notify(NodeRuntime& n);
  bool heartbeat_consumer() const { return config_->timing.heartbeat_timeout.count() > 0; }
  std::vector<uint32_t> receive_ids() const;
  NodeRuntime& node(int node_index);
  const NodeRuntime& node(int node_index) const;

  asio::any_io_executor executor_;
  RetainedConfigs config_owners_;
  const BusConfig* config_;
  const FrameFamily& family_;
  int first_node_index_;
  NodeUpdated on_update_;
  std::unique_ptr<CanChannel> channel_;
  PollPlan plan_;
  std::vector<canopen::PollJob> jobs_;  // parallel to plan_.items()
  std::vector<std::unique_ptr<NodeRuntime>> nodes_;
  std::map<uint32_t, NodeRuntime*> by_cob_;  // every COB-ID a node sends on
  asio::steady_timer wake_;                  // run(): back-off, waiting for workers
  asio::steady_timer supervisor_wake_;
  BusCounters counters_;
  CanCounters can_counters_;
  bool stopping_ = false;
  bool link_up_ = false;
  bool link_error_logged_ = false;
  int workers_running_ = 0;
  SteadyTime error_frames_logged_{};
  uint64_t error_frames_unlogged_ = 0;
  WireTrace trace_;
};

}  // namespace fieldgate
