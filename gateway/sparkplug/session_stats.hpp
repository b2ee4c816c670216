#pragma once

#include <cstdint>

namespace fieldgate::sparkplug {

// Counters of the MQTT session, for the Prometheus endpoint (gateway/metrics/metrics.cpp).
struct SessionStats {
  bool connected = false;  // MQTT session up (CONNACK accepted)
  bool born = false;       // NBIRTH published in this session
  bool waiting_for_primary_host = false;
  uint64_t bd_seq = 0;             // of the current (or next) session
  uint64_t connects = 0;           // CONNACKs accepted
  uint64_t connect_failures = 0;   // attempts that did not reach a session
  uint64_t connection_losses = 0;  // sessions that ended without our asking
  uint64_t messages_published = 0;
  uint64_t bytes_published = 0;
  uint64_t publish_failures = 0;
  uint64_t births = 0;  // NBIRTH + DBIRTH
  uint64_t deaths = 0;  // DDEATH + NDEATH published (not the will)
  uint64_t rebirth_requests = 0;
  uint64_t commands_received = 0;  // DCMD metrics
  uint64_t commands_rejected = 0;  // disabled, unknown or not writable metric, bad value
  uint64_t commands_failed = 0;    // refused by the write path or the controller
  uint64_t commands_unknown = 0;   // outcome unknown (no reply, timeout)
  uint64_t commands_completed = 0;
  uint64_t malformed_messages = 0;
};

}  // namespace fieldgate::sparkplug
