#pragma once

// What the serial families' fault property tests (tests/families/*/*_fault_property_test.cpp)
// share: the Modbus outcomes a write may have under faults, and the check that a run was not
// vacuous.

#include <gtest/gtest.h>

#include <cstddef>
#include <vector>

#include "harness.hpp"

namespace fieldgate::test {

inline constexpr int kTargetFailed = 0x0B, kDeviceFailure = 0x04;
// The test client got no answer within its 5 s (or, on the same connection after one, another
// request's answer): the host was too loaded to run the daemon. No confirmation.
inline constexpr int kNoAnswer = -1;

// A Modbus answer arrived: success, or an exception the gateway sent. Otherwise the connection
// may take a late answer for the next request's, and the test opens a fresh one.
inline bool answered(int exception) {
  return exception >= 0 && exception <= kTargetFailed;
}

// The outcomes a write may have under faults: confirmed, outcome unknown (0x0B), refused by
// the device (0x04), or no answer at the test client.
inline bool expected_write_outcome(int exception) {
  return exception == 0 || exception == kTargetFailed || exception == kDeviceFailure ||
         exception == kNoAnswer;
}

// Not vacuous: faults happened, and writes still got through.
inline void expect_faults_and_confirmed_writes(int successes, int unknown, std::size_t writes,
                                               const std::vector<JournalEntry>& journal) {
  EXPECT_GE(successes, 3) << unknown << " answered 0x0B of " << writes;
  EXPECT_GT(unknown, 0);
  int faulted = 0;
  for (const auto& e : journal) faulted += e.fault.empty() ? 0 : 1;
  EXPECT_GT(faulted, 10);
}

}  // namespace fieldgate::test
