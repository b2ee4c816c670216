// The points of one CANopen node's model as the bus reads them: each point's source (an SDO
// object, a TPDO slot, or a value the gateway consumed from the node), the poll job a polled
// point gives, and the values that TPDOs, transfers and the node's status hold for the points.
// Pure: the bus runtime schedules the jobs and stores the values into its process image.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "drivers/canopen/canopen_request.hpp"
#include "drivers/canopen/canopen_time.hpp"
#include "drivers/canopen/node_supervision.hpp"
#include "drivers/protocol_family.hpp"
#include "drivers/transport/can_frame.hpp"
#include "mapping/model.hpp"

namespace fieldgate::canopen {

// What a poll of a point does: an SDO upload, an SDO upload only while the point's TPDO is
// older than the poll period, or a refresh of a value the gateway consumed.
struct PollJob {
  enum class Kind { sdo, tpdo_fallback, local };
  Kind kind = Kind::sdo;
  ObjectAddress object;
  uint32_t tpdo_cob = 0;

  friend bool operator==(const PollJob&, const PollJob&) = default;
};

// The request a poll job stands for in the poll plan: "read 0x6064:0 INTEGER32", or "local".
Request poll_request(const PollJob& job);

// A value for a model point.
struct PointUpdate {
  int point = 0;
  int64_t value = 0;
};

class NodePoints {
 public:
  // Called for a read point whose source does not compile (validate_model rejects it at load; a
  // model that skipped it loses the point only).
  using OnError = std::function<void(const PointDef& point, const std::string& error)>;
  NodePoints(uint8_t node, const Model& model, const OnError& on_error);

  // The poll job of a read point, or none (a point without a source, or a TPDO point without an
  // object to fall back on).
  std::optional<PollJob> poll_job(std::size_t point) const;
  // The COB-IDs of the TPDOs the points read.
  std::vector<uint32_t> tpdo_cobs() const;
  bool reads_tpdo(uint32_t cob) const { return tpdo_points_.count(cob) > 0; }
  bool has_local_points() const { return !local_points_.empty(); }
  // The points holding the NMT state (no value once it is unknown).
  std::vector<int> nmt_state_points() const;

  // The values a TPDO holds; a point the PDO is too short for gets none, its error in `errors`.
  std::vector<PointUpdate> from_tpdo(const CanFrame& frame, std::vector<std::string>& errors) const;
  // The values the bytes of an object hold (an upload, a confirmed download) for every point
  // read from it; a point with another reading of the object (length, type) is left to its
  // own poll.
  std::vector<PointUpdate> from_object(uint16_t index, uint8_t sub,
                                       std::span<const uint8_t> bytes) const;
  // The values of the points read by SDO from an object the node does not have: 0 (for a
  // VISIBLE_STRING, the empty string). TPDO points keep what their PDO brings.
  std::vector<PointUpdate> absent_values(uint16_t index, uint8_t sub) const;
  // The local points' values from what the gateway consumed; the NMT state has none before a
  // heartbeat.
  std::vector<PointUpdate> local_values(const NodeStatus& status) const;

 private:
  uint8_t node_;
  std::vector<ValueType> types_;                     // by model point
  std::vector<std::optional<PointSource>> sources_;  // by model point
  std::map<uint32_t, std::vector<int>> tpdo_points_;
  std::vector<int> local_points_;
};

}  // namespace fieldgate::canopen
