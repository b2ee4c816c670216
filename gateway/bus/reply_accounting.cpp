#include "gateway/bus/reply_accounting.hpp"

namespace fieldgate {

ReplyOutcome count_reply(NodeCounters& c, BusCounters& bus, const Reply& reply, SteadyTime at) {
  switch (reply.status) {
    case Reply::Status::ok:
      c.consecutive_timeouts = 0;
      c.last_good = at;
      c.ever_good = true;
      return ReplyOutcome::answered;
    case Reply::Status::device_error:
      // The node answered, so it is there; the error belongs to the command.
      c.consecutive_timeouts = 0;
      ++c.errors;
      ++bus.errors;
      c.last_device_error = reply.device_code;
      c.last_error_text = reply.text;
      return ReplyOutcome::answered;
    case Reply::Status::garbled:
      ++c.errors;
      ++bus.errors;
      c.last_error_text = reply.text;
      return ReplyOutcome::garbled;
    case Reply::Status::unreachable:
      // An answer from a forwarding device (Copley e 32), not silence: counted apart from
      // timeouts, with its code, and toward offline like them.
      ++c.unreachable;
      ++bus.unreachable;
      ++c.consecutive_timeouts;
      if (reply.device_code != 0) c.last_device_error = reply.device_code;
      c.last_error_text = reply.text;
      return ReplyOutcome::failed;
    case Reply::Status::timeout:
    case Reply::Status::link_down:
      ++c.timeouts;
      ++bus.timeouts;
      ++c.consecutive_timeouts;
      c.last_error_text = reply.text;
      return ReplyOutcome::failed;
  }
  return ReplyOutcome::failed;
}

void count_latency(BusCounters& bus, double seconds) {
  std::size_t bucket = 0;
  while (bucket < std::size(kLatencyBuckets) && seconds > kLatencyBuckets[bucket]) ++bucket;
  ++bus.latency_counts[bucket];
  bus.latency_sum += seconds;
}

}  // namespace fieldgate
