// The TPDO-fresh rule: a poll that falls back on SDO is spared while its TPDO keeps the object
// fresh, with times handed in.
#include "drivers/canopen/tpdo_freshness.hpp"

#include <gtest/gtest.h>

namespace fieldgate::canopen {
namespace {

using std::chrono::milliseconds;

PollJob fallback_on(uint32_t cob) {
  PollJob job;
  job.kind = PollJob::Kind::tpdo_fallback;
  job.object = {0x6064, 0, DataType::integer32};
  job.tpdo_cob = cob;
  return job;
}

TEST(TpdoFreshness, TpdoGetsOnePeriodAfterARestart) {
  TpdoFreshness tpdos({0x181});
  const TimePoint t0{std::chrono::seconds(100)};
  const milliseconds period(50);
  EXPECT_FALSE(tpdos.keeps_fresh(fallback_on(0x181), period, t0));  // never restarted
  tpdos.restart(t0);
  EXPECT_TRUE(tpdos.keeps_fresh(fallback_on(0x181), period, t0 + milliseconds(49)));
  EXPECT_FALSE(tpdos.keeps_fresh(fallback_on(0x181), period, t0 + milliseconds(50)));
}

TEST(TpdoFreshness, ReceivedTpdoKeepsOnlyItsOwnObjectsFresh) {
  TpdoFreshness tpdos({0x181, 0x281});
  const TimePoint t0{std::chrono::seconds(100)};
  const milliseconds period(50);
  tpdos.restart(t0);
  tpdos.received(0x181, t0 + milliseconds(40));
  EXPECT_TRUE(tpdos.keeps_fresh(fallback_on(0x181), period, t0 + milliseconds(80)));
  EXPECT_FALSE(tpdos.keeps_fresh(fallback_on(0x281), period, t0 + milliseconds(80)));
}

TEST(TpdoFreshness, OnlyTpdoFallbackPollsAreSpared) {
  TpdoFreshness tpdos({0x181});
  const TimePoint t0{std::chrono::seconds(100)};
  tpdos.restart(t0);
  PollJob sdo = fallback_on(0x181);
  sdo.kind = PollJob::Kind::sdo;
  EXPECT_FALSE(tpdos.keeps_fresh(sdo, milliseconds(50), t0));
}

}  // namespace
}  // namespace fieldgate::canopen
