#pragma once

#include <chrono>
#include <string>

namespace fieldgate {

class Gateway;
class FleetWatch;

// The plant as the console shows it, as JSON: every bus with its counters, every node with its
// state, the reason and its counters, every profile axis with its PLCopen state and command,
// the Modbus listeners and, with a fleet watch, every edge node and device of the Sparkplug
// group. `wall` stamps the snapshot for the page's clock and plots. The layout is documented in
// docs/console.md.
std::string plant_json(const Gateway& gateway, std::chrono::steady_clock::time_point now,
                       std::chrono::system_clock::time_point wall,
                       const FleetWatch* fleet = nullptr);

}  // namespace fieldgate
