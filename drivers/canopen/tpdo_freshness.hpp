// When the TPDOs one node's points read last arrived, for the polls that fall back on SDO
// (PollJob::Kind::tpdo_fallback): while its TPDO keeps an object fresh, its poll needs no
// transfer. No clock of its own: the bus runtime hands in the times.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "drivers/canopen/canopen_time.hpp"
#include "drivers/canopen/node_points.hpp"
#include "drivers/transport/can_frame.hpp"

namespace fieldgate::canopen {

class TpdoFreshness {
 public:
  // `cobs`: the COB-IDs of the TPDOs the node's points read (NodePoints::tpdo_cobs).
  explicit TpdoFreshness(std::vector<uint32_t> cobs) : cobs_(std::move(cobs)) {}

  // The link opened or the node came online: each TPDO gets one poll period from `now` to show
  // up before its points are read by SDO.
  void restart(TimePoint now);
  void received(uint32_t cob, TimePoint now);
  // True where a poll of `job` with `period`, due at `now`, needs no transfer: its TPDO arrived
  // (or was given its chance) less than a period ago.
  bool keeps_fresh(const PollJob& job, std::chrono::microseconds period, TimePoint now) const;

 private:
  std::vector<uint32_t> cobs_;
  std::map<uint32_t, TimePoint> seen_;
};

}  // namespace fieldgate::canopen
