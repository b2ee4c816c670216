#pragma once

#include <string>
#include <vector>

#include "gateway/config/gateway_config.hpp"

namespace fieldgate {

struct BusBudget {
  std::string bus;
  double wire_seconds_per_second =
      0;  // wire time + turnaround the configured polls need per second
};

// What each bus's poll schedule costs at its baud: characters per request and reply at the
// family's estimate, plus turnaround and inter-frame gap, over each poll class period.
BusBudget compute_poll_budget(const BusConfig& bus);

}  // namespace fieldgate
