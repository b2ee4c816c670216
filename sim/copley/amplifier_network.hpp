#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sim/common/line_device_loop.hpp"
#include "sim/copley/amplifier_axis.hpp"

namespace fieldgate::sim::copley {

struct NetworkOptions {
  // CAN node IDs of the amplifiers. Node 0, the RS-232 gateway amplifier, is always present.
  std::vector<int> nodes{0};
  // Axes per node (1–3); nodes not listed have `default_axes`.
  std::map<int, int> axes;
  int default_axes = 1;
  bool stepper = false;
  // Rate the gateway amplifier's serial port runs at when the simulator starts.
  std::uint32_t baud = 9600;
  // Latency of a command forwarded over CAN, on top of the serial turnaround.
  std::chrono::microseconds forward_latency{0};
  // How long a node stays deaf after a reset.
  std::chrono::milliseconds boot_time{0};
  // Reply `v1200` instead of `v 1200` (§2.8 shows both spellings).
  bool compact_replies = false;
  // A command without an axis letter to a multi-axis amplifier: the manual says the letter is
  // "necessary" but not what happens without it. Axis a, e 33, or no reply at all.
  enum class MissingAxis { first_axis, parse_error, silent };
  MissingAxis missing_axis = MissingAxis::first_axis;
  // The prefix "0 " (whether it addresses the gateway is not shown): the gateway itself, e 31
  // (no such forwarding target), or e 32 after the CAN timeout (forwarded to nobody).
  enum class ZeroPrefix { gateway, invalid_node, can_failure };
  ZeroPrefix zero_prefix = ZeroPrefix::gateway;
  // The gateway amplifier's CAN timeout: e 32 for an absent or deaf node comes this late.
  std::chrono::milliseconds can_timeout{0};
};

// The amplifiers on one RS-232 link: node 0 on the serial port and the nodes it reaches over
// CAN. Takes CR-terminated request lines and returns what the serial port sends back.
class AmplifierNetwork {
 public:
  AmplifierNetwork(NetworkOptions options, SimTime now);

  // Copley requests end at CR; LF is not part of the protocol and stays in the next request.
  static std::size_t frame(std::string_view pending);
  DeviceReply handle(std::string_view request, SimTime now);

  // Family commands of the control channel: node-off N, node-on N, reset N, fault N[.x] BITS,
  // inputs N[.x] MASK. Returns nullopt for other verbs. A reset of node 0 changes the link rate;
  // `link_baud_changed` tells the caller.
  std::optional<std::string> control(std::string_view verb, std::span<const std::string> arguments,
                                     SimTime now, std::optional<std::uint32_t>& link_baud_changed);
  static std::string control_help();

  // For tests and the control channel; nullptr if the node or axis does not exist.
  AmplifierAxis* axis(int node, char letter = 'a');
  std::int32_t cvm_register(int node, int index) const;

 private:
  struct Node {
    std::vector<AmplifierAxis> axes;
    std::array<std::int32_t, 32> cvm{};
    bool online = true;
    SimTime deaf_until{};
  };

  Node* find(int id);
  void reset(Node& node, SimTime now);
  std::string execute(Node& node, AmplifierAxis& axis, const Command& command, SimTime now,
                      std::optional<std::uint32_t>& new_baud, bool gateway);

  NetworkOptions options_;
  std::map<int, Node> nodes_;
};

// Parses "3,5,7" into node IDs and "2" or "0:1,3:2" into axis counts (for the CLI).
std::vector<int> parse_node_list(std::string_view text);
void parse_axes(std::string_view text, NetworkOptions& options);

}  // namespace fieldgate::sim::copley
