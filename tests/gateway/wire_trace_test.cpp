#include "gateway/bus/wire_trace.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "drivers/printable_bytes.hpp"

namespace fieldgate {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::microseconds;
using std::chrono::milliseconds;

Clock::time_point at_us(int64_t us) {
  return Clock::time_point(microseconds(us));
}

class WireTraceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    WireTrace::set_sink([this](std::string_view line) { lines_.emplace_back(line); });
  }
  void TearDown() override { WireTrace::set_sink({}); }
  std::vector<std::string> lines_;
};

TEST(TraceLine, CandumpLikeFieldsWithEscapedBytesLast) {
  EXPECT_EQ(format_trace_line("ims", at_us(12053327011), "ims_a", TraceDirection::tx, "ok",
                              printable_bytes("AZ\n")),
            "trace ims (12053.327011) ims_a tx ok 'AZ\\n'");
  EXPECT_EQ(format_trace_line("copley-rs232", at_us(5), "axis_3", TraceDirection::rx, "unreachable",
                              printable_bytes("e 32\r")),
            "trace copley-rs232 (0.000005) axis_3 rx unreachable 'e 32\\r'");
  // A two-word outcome stays one field (found on the demo: "garbled reply" broke the split).
  EXPECT_EQ(format_trace_line("chain", at_us(5), "table_1", TraceDirection::tx, "device error",
                              printable_bytes("X\r")),
            "trace chain (0.000005) table_1 tx device_error 'X\\r'");
  // A protocol file's words for the frame follow the bytes, which end at the next quote: a quote
  // or a backslash among them is escaped.
  EXPECT_EQ(format_trace_line("smc", at_us(5), "smc_1", TraceDirection::rx, "ok",
                              printable_bytes("1TS000033\r\n"), "read_state errors=0000 state=33"),
            "trace smc (0.000005) smc_1 rx ok '1TS000033\\r\\n' read_state errors=0000 state=33");
  EXPECT_EQ(format_trace_line("p", at_us(5), "axis_1", TraceDirection::rx, "ok",
                              printable_bytes("*'a\\b"), "name"),
            "trace p (0.000005) axis_1 rx ok '*\\x27a\\x5cb' name");
  // Outside a transaction neither node nor outcome is known; control bytes are escaped.
  EXPECT_EQ(format_trace_line("ims", at_us(1000000), "", TraceDirection::tx, "",
                              printable_bytes(std::string("\x1b\x03 x", 4))),
            "trace ims (1.000000) - tx - '\\x1b\\x03 x'");
}

TEST(TokenBucketTest, BurstThenRate) {
  TokenBucket bucket(10, 3);  // 10 per second, bursts of 3
  const auto t0 = at_us(1000000);
  EXPECT_TRUE(bucket.take(t0));
  EXPECT_TRUE(bucket.take(t0));
  EXPECT_TRUE(bucket.take(t0));
  EXPECT_FALSE(bucket.take(t0));
  EXPECT_FALSE(bucket.take(t0 + milliseconds(50)));  // half a token
  EXPECT_TRUE(bucket.take(t0 + milliseconds(100)));  // one token back
  EXPECT_FALSE(bucket.take(t0 + milliseconds(100)));
  // A long pause refills to the burst, not beyond.
  const auto later = t0 + std::chrono::seconds(60);
  int taken = 0;
  while (bucket.take(later)) ++taken;
  EXPECT_EQ(taken, 3);
}

TEST_F(WireTraceTest, OffByDefaultAndSwitchable) {
  WireTrace trace("bus1");
  trace.emit(at_us(1), "n", TraceDirection::tx, "ok", "x");
  EXPECT_TRUE(lines_.empty());
  EXPECT_EQ(WireTrace::set("bus1", true), 1);
  EXPECT_EQ(WireTrace::set("nosuch", true), 0);
  trace.emit(at_us(2), "n", TraceDirection::tx, "ok", "x");
  ASSERT_EQ(lines_.size(), 1u);
  EXPECT_EQ(lines_[0], "trace bus1 (0.000002) n tx ok 'x'");
}

TEST_F(WireTraceTest, RateLimitCountsAndReportsDroppedLines) {
  WireTrace trace("busr", true, 10, 2);
  const auto t0 = at_us(5000000);
  for (int i = 0; i < 5; ++i) trace.emit(t0, "n", TraceDirection::rx, "ok", "y");
  EXPECT_EQ(lines_.size(), 2u);
  EXPECT_EQ(trace.lines(), 2u);
  EXPECT_EQ(trace.dropped(), 3u);
  trace.emit(t0 + milliseconds(100), "n", TraceDirection::rx, "ok", "z");
  ASSERT_EQ(lines_.size(), 4u);
  EXPECT_EQ(lines_[2], "trace busr: 3 line(s) dropped by the rate limit (3 in all)");
  EXPECT_EQ(lines_[3], "trace busr (5.100000) n rx ok 'z'");
}

TEST_F(WireTraceTest, ToggleAllSwitchesEveryBus) {
  WireTrace a("a", true);
  WireTrace b("b", false);
  EXPECT_TRUE(WireTrace::toggle_all());  // one was off: all on
  EXPECT_TRUE(a.enabled());
  EXPECT_TRUE(b.enabled());
  EXPECT_FALSE(WireTrace::toggle_all());
  EXPECT_FALSE(a.enabled());
  EXPECT_FALSE(b.enabled());
}

TEST_F(WireTraceTest, HttpControl) {
  WireTrace a("ims", false);
  WireTrace b("copley", false);
  auto r = trace_control("/trace?bus=ims&on=1");
  EXPECT_EQ(r.status, 200);
  EXPECT_TRUE(a.enabled());
  EXPECT_FALSE(b.enabled());
  EXPECT_EQ(r.body, "trace ims: on (0 line(s), 0 dropped)\n");
  r = trace_control("/trace?on=0");
  EXPECT_EQ(r.status, 200);
  EXPECT_FALSE(a.enabled());
  EXPECT_EQ(trace_control("/trace?bus=nosuch&on=1").status, 404);
  EXPECT_EQ(trace_control("/trace?bus=ims&on=maybe").status, 400);
  EXPECT_EQ(trace_control("/trace?bus=ims").status, 400);
  EXPECT_EQ(trace_control("/trace?bus=ims&on=1&x=2").status, 400);
  EXPECT_EQ(trace_control("/tracex?on=1").status, 404);
  EXPECT_FALSE(a.enabled());
}

}  // namespace
}  // namespace fieldgate
