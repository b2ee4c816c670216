// Several simulated nodes sharing one CAN bus, and the simulator's line commands.
#pragma once

#include "can_frame.hpp"
#include "node.hpp"

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate::sim::canopen {

// "2,3" or "1-4,10": node IDs 1..127; throws std::invalid_argument with a message.
std::vector<std::uint8_t> parse_node_ids(std::string_view text);

class Network {
 public:
  Network(NodeConfig config, FrameSink sink, LogSink log = {});

  // Adds a node and powers it on (boot-up message).
  Node& add_node(std::uint8_t id, TimePoint now);
  Node* node(std::uint8_t id);
  std::vector<std::uint8_t> ids() const;

  void receive(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  TimePoint next_deadline() const;

  struct CommandResult {
    bool ok = true;
    bool quit = false;
    std::string message;
  };
  // power-off ID | power-on ID | fault ID CODE | status [ID] | quit | help
  CommandResult execute(std::string_view line, TimePoint now);

 private:
  NodeConfig config_;
  FrameSink sink_;
  LogSink log_;
  std::map<std::uint8_t, std::unique_ptr<Node>> nodes_;
};

}  // namespace fieldgate::sim::canopen
