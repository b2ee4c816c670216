// The CANopen core's clock: its timers, SDO timeouts and heartbeat ages are steady time points,
// passed in by the caller (the core reads no clock itself).
#pragma once

#include <chrono>

namespace fieldgate::canopen {

using Clock = std::chrono::steady_clock;
using TimePoint = Clock::time_point;

}  // namespace fieldgate::canopen
