#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/awaitable.hpp>
#include <boost/asio/steady_timer.hpp>

#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/link.hpp"
#include "drivers/protocol_family.hpp"
#include "drivers/transport/byte_transport.hpp"
#include "gateway/bus/bus.hpp"
#include "gateway/bus/bus_turn.hpp"
#include "gateway/bus/pending_command.hpp"
#include "gateway/bus/poll_failure_report.hpp"
#include "gateway/bus/poll_plan.hpp"
#include "gateway/bus/retained_configs.hpp"
#include "gateway/bus/wire_trace.hpp"
#include "gateway/config/gateway_config.hpp"
#include "gateway/image/process_image.hpp"

namespace fieldgate {

// Owns one field link: the only coroutine that touches its transport. Serialises commands from
// Modbus writes (first) with polls (spread over time), one transaction in flight.
class SerialBus final : public Bus {
 public:
  // config_owner keeps the configuration that config belongs to alive as long as the bus runs,
  // which a reload may make longer than that configuration is in force.
  SerialBus(asio::any_io_executor executor, std::shared_ptr<const void> config_owner,
            const BusConfig& config, int first_node_index, NodeUpdated on_update);
  // What the bus reads as the time: the steady clock, or in tests a clock they set.
  using TimeSource = std::function<SteadyTime()>;
  // On a transport the caller made (tests: an in-memory line) instead of the configured one, and
  // on a time source of the caller's (tests: literal times; see recheck()) for every decision:
  // polls due, probes, reopening, a command's patience. The line's own reply and byte timeouts,
  // the transaction latency and the wire trace stay on the steady clock: they measure the wire.
  SerialBus(asio::any_io_executor executor, std::shared_ptr<const void> config_owner,
            const BusConfig& config, int first_node_index, NodeUpdated on_update,
            std::unique_ptr<ByteTransport> transport, TimeSource now = {});
  ~SerialBus() override;

  // Runs until stop(); spawn it on the io_context.
  asio::awaitable<void> run() override;
  void stop() override;
  // A bus waiting for its next poll decides again at once: what a test calls after moving the
  // time source on, since the bus's sleep runs on the steady clock.
  void recheck() { wake_.cancel(); }

  // Queues a command ahead of polls and returns its reply once the device answered (or failed).
  // A command for an offline node fails at once as unreachable.
  asio::awaitable<Reply> submit(int node_index, Request request,
                                CommandOptions options = {}) override;

  const BusConfig& config() const override { return *config_; }
  const BusCounters& counters() const override { return counters_; }
  const LinkStats& link_stats() const { return link_.stats(); }
  WireTrace& trace() override { return trace_; }
  bool owns_node(int node_index) const;
  const NodeConfig& node_config(int node_index) const override;
  std::vector<std::shared_ptr<NodeImage>> node_images() const override;
  void rebind(int first_node_index, NodeUpdated on_update) override;
  // In place when the bus's own part of the configuration (all but `nodes:`) is unchanged and
  // every node it runs is still configured as the same device (NodeConfig::identity): a family
  // keeps what it learned of the nodes bound to it, so a node taken away or changed rebuilds the
  // bus (Gateway::carry_over keeps its neighbours served meanwhile).
  bool reconfigure(std::shared_ptr<const void> config_owner, const BusConfig& config,
                   int first_node_index, NodeUpdated on_update) override;
  int first_node_index() const override { return first_node_index_; }

 private:
  struct NodeRuntime {
    int index = 0;  // position on this bus
    const NodeConfig* config = nullptr;
    NodeContextPtr family_context;            // the family's, from bind_node
    std::shared_ptr<const void> bound_owner;  // the configuration family_context was bound from
    std::shared_ptr<NodeImage> image;
    SteadyTime next_probe{};
    LinkTiming timing;      // the bus's, with the node's reply timeout
    int poll_items = 0;     // distinct poll requests of the node
    int refused_polls = 0;  // polls in a row the node answered with a device error
    PollFailureReport failure_report;
  };
  static constexpr int kProofAttemptsPerCall = 3;
  static constexpr std::chrono::milliseconds kCommandPatience{1000};

  // A node's runtime, bound to the family (which may learn from it, e.g. a chain's units).
  std::shared_ptr<NodeRuntime> bind(const NodeConfig& node, int index,
                                    std::shared_ptr<const void> owner);
  // The poll plan of nodes_: one poll item per distinct request (points that share a reply share
  // a transaction), and each image's polled points.
  void plan_polls();
  asio::awaitable<void> open_link();
  // `sent_ahead`: the request went out ahead (Link::send_ahead); its first attempt takes it over.
  asio::awaitable<Reply> transact(NodeRuntime& node, const Request& request, int retries,
                                  bool accept_no_reply, bool poll, bool sent_ahead = false);
  std::shared_ptr<PendingCommand> take_command();
  // After a timeout, a garbled reply or stray bytes: the family drains the line until quiet.
  // `heard`: bytes came back in the failed exchange.
  asio::awaitable<void> resync(NodeRuntime& node, const Reply& failed, bool heard);
  // Runs the family's proof of alignment (the node first, then any node not offline) and
  // records whether the line is in step.
  // `node`: the node of the failed exchange (or of the next request); `heard`: whether it sent
  // anything in that exchange (a garbled or late reply), as opposed to silence.
  asio::awaitable<void> prove_aligned(NodeRuntime& node, bool heard);
  asio::awaitable<void> run_poll(std::size_t item_index, bool sent_ahead = false);
  // What run() decides from at `now`, with `due` as the plan's offer.
  BusTurnInput turn_input(SteadyTime now, std::optional<PollPlan::Due> due) const;
  // Pipelining: while poll `current` is on the wire, the poll that would follow it (when no
  // command waits) is chosen and its request prepared; the moment its reply is accepted the
  // request goes out (send_armed_poll), and run() makes it the next transaction. Nothing is sent
  // ahead of a command, a probe, an inter-frame gap or a line out of step.
  void arm_next_poll(std::size_t current);
  void send_armed_poll();
  // A request sent ahead that will not get its exchange: its reply is owed, and no reply is
  // trusted until a proof of alignment passed.
  void abandon_sent_ahead();
  void record(NodeRuntime& node, const Reply& reply, bool poll);
  void record_latency(double seconds);
  void set_state(NodeRuntime& node, NodeState state, std::string_view why);
  void all_nodes_offline(std::string_view why);
  bool all_nodes_offline_now() const;
  NodeRuntime& node(int node_index);

  asio::any_io_executor executor_;
  TimeSource now_;
  RetainedConfigs config_owners_;
  const BusConfig* config_;
  ProtocolFamily& family_;  // the stream shape of the first configuration's family
  int first_node_index_;
  NodeUpdated on_update_;
  std::unique_ptr<ByteTransport> transport_;
  Link link_;
  PollPlan plan_;
  uint64_t plan_number_ = 0;  // a poll under way completes its item only in the plan it ran from
  // Shared: a transaction under way holds its node across a reconfigure, which reorders them.
  std::vector<std::shared_ptr<NodeRuntime>> nodes_;
  std::deque<std::shared_ptr<PendingCommand>> commands_;
  asio::steady_timer wake_;
  BusCounters counters_;
  bool stopping_ = false;
  int commands_in_row_ = 0;
  int command_credit_ = kCommandCreditMax;  // see next_bus_turn
  int last_command_node_ = -1;
  bool link_error_logged_ = false;
  // Reopens of a link that stayed up only briefly (nothing answers, so it is reopened every
  // probe interval): logged at debug, with a notice every kReopenReminder.
  int quiet_reopens_ = 0;
  SteadyTime open_noticed_at_{};
  // False from a failed exchange until a proof of alignment passed: no reply is trusted meanwhile.
  bool aligned_ = true;
  int failed_proof_rounds_ = 0;  // calls of prove_aligned() that failed in a row
  bool alignment_failure_logged_ = false;
  // Replies the line may still owe: requests that got none (drivers/alignment_proof.hpp).
  AlignmentDebt debt_;
  std::string drained_before_proof_;      // what resync drained since the last proof
  NodeRuntime* last_answered_ = nullptr;  // the node whose reply was last taken, for proofs
  // Wire trace: during a transaction the link's bytes wait here for its outcome.
  struct TracedBytes {
    SteadyTime at;
    bool tx;
    std::string bytes;
    std::string label;  // the family's words for the frame (Link::label_last_frame)
  };
  WireTrace trace_;
  bool trace_collecting_ = false;
  std::vector<TracedBytes> traced_;
  // Collects the link's frames (and the family's labels) while the trace is wanted.
  void collect_trace(bool on);
  void trace_transaction(const NodeRuntime& node, std::string_view outcome);
  // What the family noted on the link, at its levels, with the bus's name. `quiet`: the routine
  // reopen of a line where nothing answers, whose notices are logged at debug.
  void log_notes(bool quiet);
  SteadyTime opened_at_{};
  struct PollAhead {
    std::shared_ptr<NodeRuntime> node;
    std::size_t item = 0;
    uint64_t plan = 0;  // plan_number_ when chosen
    std::string bytes;  // the family's request (ProtocolFamily::pipelined_request)
  };
  std::optional<PollAhead> armed_;  // chosen, not sent
  std::optional<PollAhead> ahead_;  // sent: the next transaction on the line
};

}  // namespace fieldgate
