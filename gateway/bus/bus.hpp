#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/awaitable.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <iterator>
#include <memory>
#include <optional>
#include <vector>

#include "drivers/protocol_family.hpp"
#include "gateway/config/gateway_config.hpp"
#include "gateway/image/process_image.hpp"

namespace fieldgate {

struct CommandOptions {
  bool accept_no_reply = false;  // silence counts as success (e.g. a reset)
  // Sent at once, even while another transaction occupies the line (e.g. a stop byte during a
  // move that holds the line until it ends); the family decides what that means on the wire.
  bool urgent = false;
  // Called when the command leaves the bus's queue for the wire. An early-confirmed step counts
  // its patience from then: queued behind a slow poll, the command is not running yet.
  std::function<void()> on_sent;
};

// Upper bounds (seconds) of the transaction latency histogram buckets; the last is +Inf.
inline constexpr double kLatencyBuckets[] = {0.001, 0.002, 0.005, 0.01, 0.02,
                                             0.05,  0.1,   0.2,   0.5,  1.0};

struct BusCounters {
  uint64_t bytes_sent = 0;
  uint64_t bytes_received = 0;
  std::array<uint64_t, std::size(kLatencyBuckets) + 1> latency_counts{};  // not cumulative
  double latency_sum = 0;                                                 // seconds
  uint64_t transactions = 0;
  uint64_t timeouts = 0;
  uint64_t unreachable = 0;  // a forwarding device said the node is not reachable
  uint64_t errors = 0;
  uint64_t retries = 0;
  uint64_t reconnects = 0;
  uint64_t commands = 0;
  // Serial buses: guard periods waited after a failed exchange, and the late or stray bytes
  // drained during them.
  uint64_t resyncs = 0;
  uint64_t resync_bytes = 0;
  // Proofs that the line is in step (drivers/alignment_proof.hpp) run after such a failure,
  // those that failed, and the stray replies they drained.
  uint64_t alignment_proofs = 0;
  uint64_t alignment_failures = 0;
  uint64_t stray_replies = 0;
  // Serial buses: polls whose request went out the moment the reply before it was accepted
  // (drivers/README.md, "Sending ahead"), and those whose exchange did not take it over (their
  // reply owed, the line proven in step again).
  uint64_t sent_ahead = 0;
  uint64_t sent_ahead_lost = 0;
  bool link_up = false;
  bool open_attempted = false;  // the first open finished, successfully or not
};

// What only a CAN bus counts (its BusCounters' bytes_sent/bytes_received count the frames' data
// bytes).
struct CanCounters {
  uint64_t frames_sent = 0;
  uint64_t frames_received = 0;
  uint64_t error_frames = 0;  // error frames from the CAN controller or driver, all classes
  uint64_t bus_off = 0;       // error frames that reported bus-off
  uint64_t rx_dropped = 0;    // frames the kernel dropped because the receive queue was full
  uint64_t tx_dropped = 0;    // frames never sent: the transmit queue stayed full
};

// One field link with its own scheduler. Serial links carry one transaction at a time
// (SerialBus); a CAN bus overlaps transfers of different nodes.
class Bus {
 public:
  using NodeUpdated = std::function<void(int node_index)>;

  virtual ~Bus() = default;
  // Runs until stop(); spawn it on the io_context.
  virtual asio::awaitable<void> run() = 0;
  virtual void stop() = 0;
  // Queues a command ahead of polls and returns its reply once the device answered (or failed).
  // A command for an offline node fails at once as unreachable.
  virtual asio::awaitable<Reply> submit(int node_index, Request request,
                                        CommandOptions options = {}) = 0;
  virtual const BusConfig& config() const = 0;
  virtual const BusCounters& counters() const = 0;
  // A CAN bus's frame counters; null on every other bus.
  virtual const CanCounters* can_counters() const { return nullptr; }
  virtual class WireTrace& trace() = 0;
  virtual const NodeConfig& node_config(int node_index) const = 0;
  // The bus's nodes' images, in config order; the process image points at them, so they
  // survive a reload that keeps the bus.
  virtual std::vector<std::shared_ptr<NodeImage>> node_images() const = 0;
  // After a reload that kept this bus: its first node's new gateway-wide number.
  virtual void rebind(int first_node_index, NodeUpdated on_update) = 0;
  // After a reload that changed only the bus's nodes (its link, protocol and timing as they
  // were): takes the new configuration without reopening the link, so its other nodes are not
  // disturbed. Each node it already runs keeps its state, values and place in the family; new
  // nodes start. False, with nothing changed, when the bus must be rebuilt instead.
  virtual bool reconfigure(std::shared_ptr<const void> /*config_owner*/,
                           const BusConfig& /*config*/, int /*first_node_index*/,
                           NodeUpdated /*on_update*/) {
    return false;
  }
  virtual int first_node_index() const = 0;
  // Counts the reloads that may have renumbered the bus's nodes (rebind, reconfigure): a caller
  // that looked a node's number up before (an action's later step) looks it up again.
  uint64_t numbering() const { return numbering_; }
  // The gateway-wide number of the node with this image now; none when the bus no longer runs it.
  std::optional<int> number_of(const NodeImage& image) const;
  // The node looked up as `number` while the bus's numbering was `numbering`: the same number
  // unless a reload renumbered the bus since, else number_of(image).
  std::optional<int> number_now(int number, uint64_t numbering, const NodeImage& image) const {
    return numbering == numbering_ ? std::optional<int>(number) : number_of(image);
  }

 protected:
  uint64_t numbering_ = 0;
};

std::shared_ptr<Bus> make_bus(asio::any_io_executor executor,
                              std::shared_ptr<const void> config_owner, const BusConfig& config,
                              int first_node_index, Bus::NodeUpdated on_update);
// The CAN bus runtime (gateway/bus/can_bus.cpp), for buses with `can:`.
std::shared_ptr<Bus> make_can_bus(asio::any_io_executor executor,
                                  std::shared_ptr<const void> config_owner, const BusConfig& config,
                                  int first_node_index, Bus::NodeUpdated on_update);

}  // namespace fieldgate
