#pragma once

#include "drivers/protocol_family.hpp"
#include "gateway/bus/bus.hpp"
#include "gateway/image/process_image.hpp"

namespace fieldgate {

// What a transaction's reply says about its node, once counted.
enum class ReplyOutcome {
  answered,  // ok or a device error: the node is there
  garbled,   // bytes that were no valid reply: counted, says nothing about presence
  failed,    // timeout, unreachable, link down: counts toward offline
};

// Counts a reply into the node's and the bus's counters (shared by every bus); the bus then
// applies its own online/offline policy to the outcome.
ReplyOutcome count_reply(NodeCounters& node, BusCounters& bus, const Reply& reply, SteadyTime at);

// Counts a transaction's latency into the bus's histogram (kLatencyBuckets).
void count_latency(BusCounters& bus, double seconds);

}  // namespace fieldgate
