#include "sim/common/wire_pacing.hpp"

#include <gtest/gtest.h>

#include "tests/sim/sim_time.hpp"

namespace fieldgate::sim {
namespace {

using namespace std::chrono_literals;
using test::kT0;

TEST(WireTiming, CharacterFrames) {
  EXPECT_EQ(FrameFormat{}.bits_per_character(), 10u);  // 8N1
  EXPECT_EQ((FrameFormat{7, Parity::even, 2}.bits_per_character()), 11u);
  EXPECT_EQ(WireTiming(9600).character_time(), 1041666ns);
  EXPECT_EQ(WireTiming(115200).character_time(), 86805ns);
  // Whole counts are computed at once: 9600 characters at 9600 baud take exactly 10 s.
  EXPECT_EQ(WireTiming(9600).wire_time(9600), 10s);
  EXPECT_EQ(WireTiming(19200, {7, Parity::odd, 1}).wire_time(192), 100ms);
  EXPECT_THROW(WireTiming(0), std::invalid_argument);
}

TEST(PacedTransmitter, ReleasesEachByteWhenItsStopBitHasLeft) {
  const WireTiming timing(9600);  // ~1.04 ms per character: one per chunk at 1 ms granularity
  PacedTransmitter tx;
  const SimTime end = tx.enqueue(kT0, "v 0\r", &timing);
  EXPECT_EQ(end, kT0 + timing.wire_time(4));
  std::string out;
  tx.release(kT0 + 1ms, out);
  EXPECT_EQ(out, "");
  EXPECT_EQ(tx.next_due(), kT0 + timing.wire_time(1));
  tx.release(kT0 + 1100us, out);
  EXPECT_EQ(out, "v");
  tx.release(kT0 + 3200us, out);
  EXPECT_EQ(out, "v 0");
  tx.release(end, out);
  EXPECT_EQ(out, "v 0\r");
  EXPECT_TRUE(tx.idle());
  EXPECT_FALSE(tx.next_due());
}

TEST(PacedTransmitter, SendsChunksAtHighRates) {
  const WireTiming timing(115200);  // 86.8 us per character: 11 per 1 ms chunk
  PacedTransmitter tx;
  const std::string reply(100, 'x');
  tx.enqueue(kT0, reply, &timing);
  std::string out;
  tx.release(kT0 + timing.wire_time(11), out);
  EXPECT_EQ(out.size(), 11u);
  int wakeups = 1;
  while (const auto due = tx.next_due()) {
    tx.release(*due, out);
    ++wakeups;
  }
  EXPECT_EQ(out, reply);
  EXPECT_EQ(wakeups, 10);  // ceil(100 / 11)
}

TEST(PacedTransmitter, QueuesBehindTheTransmissionInProgress) {
  const WireTiming timing(9600);
  PacedTransmitter tx;
  const SimTime first = tx.enqueue(kT0, "ok\r", &timing);
  const SimTime second = tx.enqueue(kT0, "ok\r", &timing);
  EXPECT_EQ(second, first + timing.wire_time(3));
  EXPECT_EQ(tx.line_free(), second);
}

TEST(PacedTransmitter, WithoutTimingEverythingLeavesAtTheStart) {
  PacedTransmitter tx;
  tx.enqueue(kT0 + 5ms, "ok\r", nullptr);
  std::string out;
  tx.release(kT0 + 4ms, out);
  EXPECT_EQ(out, "");
  tx.release(kT0 + 5ms, out);
  EXPECT_EQ(out, "ok\r");
}

TEST(ReceiveWire, RequestOccupiesTheWireFromItsFirstByte) {
  WireEmulation wire{true, WireTiming(9600), 0us};
  ReceiveWire rx;
  rx.first_byte(kT0);
  // A PTY delivers "g r0x32\r" at once; on a 9600 baud line it takes 8 character times.
  EXPECT_EQ(rx.complete(8, kT0, wire), kT0 + wire.timing.wire_time(8));
  // A second request in the same burst queues behind the first.
  EXPECT_EQ(rx.complete(8, kT0, wire), kT0 + wire.timing.wire_time(16));
  // A host slower than the wire: the last byte's arrival counts.
  rx.first_byte(kT0 + 1s);
  EXPECT_EQ(rx.complete(2, kT0 + 2s, wire), kT0 + 2s);
}

TEST(ReceiveWire, WithoutEmulationARequestIsCompleteWhenRead) {
  WireEmulation wire;
  ReceiveWire rx;
  rx.first_byte(kT0);
  EXPECT_EQ(rx.complete(100, kT0 + 1ms, wire), kT0 + 1ms);
}

}  // namespace
}  // namespace fieldgate::sim
