// The frame shape of a family (Family, drivers/protocol_family.hpp). A stream family
// (ProtocolFamily) exchanges bytes over a Link, one transaction at a time on the line. A frame
// family runs on a frame bus (CAN): whole frames go out through a FramePort, frames come in through
// the bus's receive filter (the identifiers the family names per node) and are handed to the node
// they belong to, and every node runs its own transactions, so transactions of different nodes
// overlap on the wire.
//
// The bus runtime (gateway/bus/can_bus.cpp) owns the port, the per-node workers, the command
// queues ahead of polls and the online/offline accounting; the family's protocol rules (what a
// frame means, how a transfer proceeds, when a node counts as alive) live in its folder.
#pragma once

#include <boost/asio/awaitable.hpp>

#include <cstdint>
#include <string_view>
#include <vector>

#include "drivers/protocol_family.hpp"
#include "drivers/transport/can_frame.hpp"

namespace fieldgate {

// A frame bus as a node's transactions use it.
class FramePort {
 public:
  virtual ~FramePort() = default;
  // False when the frame could not go out (the link is down, or the transmit queue stayed
  // full). `outcome`: how the transaction this frame ends came out, for the wire trace.
  virtual asio::awaitable<bool> send(const CanFrame& frame, std::string_view outcome = {}) = 0;
  // False once the link went down or the bus is stopping: a waiting transaction gives up.
  virtual bool up() const = 0;
};

// What a received frame is to the node it belongs to.
enum class FrameRole {
  none,               // not the node's (or a remote request)
  transfer_response,  // answers the node's running transaction
  heartbeat,          // the node's liveness and state
  emergency,          // the node's error report
  other,              // the node's, but none of the above (e.g. only process data)
};

class FrameFamily : public Family {
 public:
  // Frames are not characters on a serial line: the serial poll budget does not apply.
  std::size_t estimate_wire_chars(const NodeAddress&, const Request&) const final { return 0; }

  // The identifiers the bus's port receives for a node of this model (its receive filter).
  virtual std::vector<uint32_t> receive_ids(const NodeAddress& node, const Model& model) const = 0;
  // The role of a frame for a node; process data (a frame whose identifier a point of the
  // node's model reads) is told apart by the bus from its points.
  virtual FrameRole classify(const NodeAddress& node, const CanFrame& frame) const = 0;
  // The node number a frame names, for the wire trace: kEveryNode for one sent to every node,
  // kNoNode for none (an error frame).
  static constexpr int kNoNode = -1;
  static constexpr int kEveryNode = -2;
  virtual int frame_node(const CanFrame& frame) const = 0;
};

}  // namespace fieldgate
