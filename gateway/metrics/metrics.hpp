#pragma once

#include <string>

namespace fieldgate {

class Gateway;

// The gateway's counters in Prometheus text exposition format (version 0.0.4): per bus
// transactions, timeouts, errors, retries, bytes and a latency histogram; per node online,
// age of the last good poll and counters; per Modbus function requests and exceptions;
// connected clients; build info.
std::string render_metrics(const Gateway& gateway);

}  // namespace fieldgate
