#include "drivers/canopen/tpdo_freshness.hpp"

namespace fieldgate::canopen {

void TpdoFreshness::restart(TimePoint now) {
  for (const uint32_t cob : cobs_) seen_[cob] = now;
}

void TpdoFreshness::received(uint32_t cob, TimePoint now) {
  seen_[cob] = now;
}

bool TpdoFreshness::keeps_fresh(const PollJob& job, std::chrono::microseconds period,
                                TimePoint now) const {
  if (job.kind != PollJob::Kind::tpdo_fallback) return false;
  const auto seen = seen_.find(job.tpdo_cob);
  return seen != seen_.end() && now - seen->second < period;
}

}  // namespace fieldgate::canopen
