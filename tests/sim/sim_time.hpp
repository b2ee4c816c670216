#pragma once

#include <chrono>

#include "sim/common/wire_pacing.hpp"

namespace fieldgate::sim::test {

// A fixed origin for injected time, far from the clock's epoch.
inline const SimTime kT0 = SimTime{} + std::chrono::hours(1000);

// kT0 + seconds.
inline SimTime at(double seconds) {
  return kT0 +
         std::chrono::duration_cast<SimClock::duration>(std::chrono::duration<double>(seconds));
}

}  // namespace fieldgate::sim::test
