// The manual's transcripts (digest §3 "Every command-level transcript" and §6 mode
// procedures), replayed against the simulator. Replies the manual shows are checked exactly
// where the simulator can honestly produce them; values that come from hardware the simulator
// does not have (an analog input at 5.25 V, a pulse train on the digital inputs) are checked
// for form only, with the reason next to the check.

#include <gtest/gtest.h>

#include "tests/families/copley_ascii/copley_bench.hpp"
#include "tests/harness/exchange_table.hpp"

namespace fieldgate::sim::copley::test {
namespace {

using fieldgate::test::Exchange;
using fieldgate::test::expect_replies;

TEST(CopleyTranscript, Section2_2_Set) {
  CopleyBench amp;
  EXPECT_EQ(amp.send("s r0x30 1200"), "ok\r");
  EXPECT_EQ(amp.send("s f0x30 1200"), "ok\r");
  EXPECT_EQ(amp.send("s r 0x30 1000"), "e 33\r");
  EXPECT_EQ(amp.send("g r0x30"), "v 1200\r") << "the rejected command changed nothing";
}

TEST(CopleyTranscript, Section2_3_Get) {
  CopleyBench amp;
  amp.send("s r0x30 1200");
  EXPECT_EQ(amp.send("g r0x30"), "v 1200\r");
  EXPECT_EQ(amp.send("g f0x17"), "e 15\r");
}

TEST(CopleyTranscript, Section2_4_Copy) {
  CopleyBench amp;
  amp.send("s r0x30 1200");
  EXPECT_EQ(amp.send("c r0x30"), "ok\r");
  EXPECT_EQ(amp.send("g f0x30"), "v 1200\r");
  amp.send("s r0x30 5");
  EXPECT_EQ(amp.send("c f0x30"), "ok\r");
  EXPECT_EQ(amp.send("g r0x30"), "v 1200\r");
}

TEST(CopleyTranscript, Section2_5_ResetHasNoReply) {
  CopleyBench amp;
  const DeviceReply reply = amp.exchange("r");
  EXPECT_EQ(reply.bytes, "");
  EXPECT_EQ(reply.new_baud, 9600u) << "the amplifier restarts at 9600 baud";
}

TEST(CopleyTranscript, Section2_6_Trajectory) {
  CopleyBench amp;
  amp.send("s r0x24 21");  // t 1 needs programmed position mode
  EXPECT_EQ(amp.send("t 1"), "ok\r");
  EXPECT_EQ(amp.send("t2"), "e 33\r");
}

TEST(CopleyTranscript, Section2_7_CvmRegisters) {
  CopleyBench amp(nodes({0, 8}));
  EXPECT_EQ(amp.send("i r0 15"), "ok\r");
  EXPECT_EQ(amp.send("i r0"), "r 15\r");
  amp.send("8 i r0 35");  // the manual's node 8 holds 35
  EXPECT_EQ(amp.send("8 i r0"), "r 35\r");
}

TEST(CopleyTranscript, Section2_8_MultiAxis) {
  NetworkOptions options = nodes({0, 2});
  options.default_axes = 3;
  options.compact_replies = true;  // §2.8 prints v1200
  CopleyBench amp(options);
  for (const char* prefix : {".b ", "2.c "}) {
    const std::string p = prefix;
    ASSERT_EQ(amp.send(p + "s r0x24 21"), "ok\r");
    ASSERT_EQ(amp.send(p + "s r0xca 1200"), "ok\r");
    ASSERT_EQ(amp.send(p + "t 1"), "ok\r");
  }
  EXPECT_EQ(amp.send(".b g r0x32", 10), "v1200\r");
  EXPECT_EQ(amp.send("2.c g r0x32", 10), "v1200\r");
  EXPECT_EQ(amp.send(".a g r0x32", 10), "v0\r") << "the other axes did not move";
}

TEST(CopleyTranscript, Section4_1_BaudChange) {
  CopleyBench amp;
  const DeviceReply reply = amp.exchange("s r0x90 19200");
  EXPECT_EQ(reply.bytes, "ok\r");
  EXPECT_EQ(reply.new_baud, 19200u) << "the ok arrives at 19200";
  // §4.1: the read-back is the nearest rate the amplifier's clock allows.
  EXPECT_NEAR(static_cast<double>(amp.value("g r0x90")), 19200, 19200 * 0.01);
}

TEST(CopleyTranscript, Section4_2_4_VelocityCommandFilter) {
  CopleyBench amp;
  EXPECT_EQ(amp.send("g r0x6B"), "v -7936 200 0 775 1550 775 -12774 32763 5813\r");
  EXPECT_EQ(amp.send("s r0x6B -7936 200 0 775 1550 775 -12774 32763 5813"), "ok\r");
  EXPECT_EQ(amp.send("g r0x6b"), "v -7936 200 0 775 1550 775 -12774 32763 5813\r");
}

TEST(CopleyTranscript, Section3_2_1_ProgrammedCurrent) {
  CopleyBench amp;
  const std::vector<Exchange> transcript = {
      {"s r0x6a 4000", "ok\r"},  // 4 A/s
      {"s r0x02 200", "ok\r"},   // 2 A
      {"s r0x24 1", "ok\r"},
      // The ramp is simulated: 0.375 s into the 4 A/s ramp the current is the manual's 1.50 A.
      {"g r0x0c", "v 150\r", "", 0.375},
      {"g r0x0c", "v 200\r", "", 1},
      {"s r0x6a 4000", "ok\r", "", 1},
      {"s r0x02 100", "ok\r", "", 1},
      {"g r0x0c", "v 150\r", "ramping down from 2 A", 1.125},
      {"s r0x24 0", "ok\r", "", 2},
      {"g r0x0c", "v 0\r", "", 2},
  };
  expect_replies(amp, transcript);
}

// A mode driven by an input the simulator does not have (an analog voltage, a PWM signal): the
// replies to setting it up and back are the manual's; its readings are checked for form only.
void input_driven_transcript(const std::vector<Exchange>& setup,
                             const std::vector<std::string>& readings,
                             const std::vector<Exchange>& teardown) {
  CopleyBench amp;
  expect_replies(amp, setup);
  for (const std::string& reading : readings) EXPECT_EQ(amp.values(reading).size(), 1u) << reading;
  expect_replies(amp, teardown);
}

TEST(CopleyTranscript, Section3_2_2_AnalogCurrent) {
  // Manual: v 525 from 5.25 V on the analog input. The simulated input reads 0 V.
  input_driven_transcript({{"s r0x19 1000", "ok\r"}, {"s r0x24 2", "ok\r"}}, {"g r0x0c"},
                          {{"s r0x19 100", "ok\r"}, {"s r0x24 0", "ok\r"}});
}

TEST(CopleyTranscript, Section3_2_3_PwmCurrent) {
  // Manual: v 500 and v 495 from a PWM input signal; the simulator has none.
  input_driven_transcript({{"s r0xa9 1000", "ok\r"}, {"s r0x24 3", "ok\r"}}, {"g r0x15", "g r0x0c"},
                          {{"s r0x24 0", "ok\r"}});
}

TEST(CopleyTranscript, Section3_3_1_ProgrammedVelocity) {
  CopleyBench amp;
  EXPECT_EQ(amp.send("s r0x36 2"), "ok\r");      // 2000 counts/s^2
  EXPECT_EQ(amp.send("s r0x37 4"), "ok\r");      // 4000 counts/s^2
  EXPECT_EQ(amp.send("s r0x2f 10000"), "ok\r");  // 1000 counts/s
  EXPECT_EQ(amp.send("s r0x24 11"), "ok\r");
  EXPECT_EQ(amp.value("g r0x18", 0.25), 5000) << "half way up the 2000 counts/s^2 ramp";
  // Manual: v 10010, a real motor's velocity ripple around 1000 counts/s.
  EXPECT_NEAR(static_cast<double>(amp.value("g r0x18", 1)), 10010, 20);
  EXPECT_EQ(amp.send("s r0x2f 5000", 1), "ok\r");  // applies at once, no t command
  EXPECT_EQ(amp.value("g r0x18", 1.0625), 7500) << "braking at 4000 counts/s^2";
  EXPECT_EQ(amp.value("g r0x18", 2), 5000);
  EXPECT_EQ(amp.send("s r0x24 0", 2), "ok\r");
  EXPECT_EQ(amp.value("g r0x18", 3), 0);
}

TEST(CopleyTranscript, Section3_3_2_AnalogVelocity) {
  // Manual: v 5000 from 5 V on the analog input; the simulated input reads 0 V.
  input_driven_transcript({{"s r0x19 10000", "ok\r"}, {"s r0x24 12", "ok\r"}}, {"g r0x18"},
                          {{"s r0x19 7000", "ok\r"}, {"s r0x24 0", "ok\r"}});
}

TEST(CopleyTranscript, Section3_3_3_PwmVelocity) {
  // Manual: v 49995 and v 49991 from a PWM input; the simulator has none.
  input_driven_transcript({{"s r0xa9 800000", "ok\r"}, {"s r0x24 13", "ok\r"}},
                          {"g r0x2c", "g r0x18"}, {{"s r0x24 0", "ok\r"}});
}

TEST(CopleyTranscript, Section3_4_2_ProgrammedPosition) {
  CopleyBench amp;
  const std::vector<Exchange> transcript = {
      {"s r0xc8 0", "ok\r"},
      {"s r0xca 40000", "ok\r"},
      {"s r0xcb 70000", "ok\r"},   // 7000 counts/s
      {"s r0xcc 200000", "ok\r"},  // 2000000 counts/s^2
      {"s r0xcd 200000", "ok\r"},
      {"s r0x24 21", "ok\r"},
      {"g r0x32", "v 0\r"},
      {"t 1", "ok\r"},
      {"g r0xa0", "v 134217728\r", "", 0.1},
  };
  expect_replies(amp, transcript);
  // Manual: v 4096 (bit 12, referenced) with the comment "bit 14 clear = not aborted". This
  // amplifier has not been homed and its profile is still running (bit 15).
  const std::int64_t trajectory = amp.value("g r0xc9", 0.1);
  EXPECT_EQ(trajectory & bit(14), 0);
  EXPECT_NE(trajectory & bit(15), 0);
  EXPECT_EQ(amp.send("s r0xc8 256", 0.1), "ok\r");
  EXPECT_EQ(amp.send("s r0xca 10000", 0.1), "ok\r");
  EXPECT_EQ(amp.send("t 1", 0.1), "ok\r");  // relative: now bound for 50000
  EXPECT_EQ(amp.send("t 0", 1), "ok\r");
  EXPECT_EQ(amp.value("g r0xa0", 2), 0) << "stopped and still enabled";
  EXPECT_NE(amp.value("g r0xc9", 2) & bit(14), 0) << "aborted";
  const std::int64_t stopped = amp.value("g r0x32", 2);
  EXPECT_GT(stopped, 6000);
  EXPECT_LT(stopped, 50000);
  EXPECT_EQ(amp.send("s r0x24 0", 2), "ok\r");
}

TEST(CopleyTranscript, Section3_4_3_AnalogPosition) {
  CopleyBench amp;
  const std::vector<Exchange> transcript = {
      {"s r0x19 4000", "ok\r"},
      {"s r0xcb 70000", "ok\r"},
      {"s r0xcc 20000", "ok\r"},
      {"s r0xcd 20000", "ok\r"},
      {"s r0x24 21", "ok\r"},  // needed for homing
      {"t 2", "ok\r"},
      {"g r0xc9", "v 8192\r", "still homing", 0.01},
      {"s r0x24 22", "ok\r", "", 0.01},
      {"t 1", "ok\r", "", 0.01},  // makes the new limits effective
  };
  expect_replies(amp, transcript);
  // Manual: v 2012, where the analog input put the axis; the simulated input reads 0 V.
  EXPECT_EQ(amp.values("g r0x32", 0.01).size(), 1u);
  EXPECT_EQ(amp.send("s r0xcb 20000", 0.01), "ok\r");
  EXPECT_EQ(amp.send("s r0x19 1000", 0.01), "ok\r");
  EXPECT_EQ(amp.send("t 1", 0.01), "ok\r");
  EXPECT_EQ(amp.send("s r0x24 0", 0.01), "ok\r");
}

void digital_position_transcript(std::string_view config, std::string_view ratio) {
  CopleyBench amp;
  EXPECT_EQ(amp.send("s r0xa8 " + std::string(config)), "ok\r");
  EXPECT_EQ(amp.send("s r0xa9 " + std::string(ratio)), "ok\r");
  EXPECT_EQ(amp.send("s r0xcb 70000"), "ok\r");
  EXPECT_EQ(amp.send("s r0xcc 20000"), "ok\r");
  EXPECT_EQ(amp.send("s r0xcd 20000"), "ok\r");
  EXPECT_EQ(amp.send("s r0x24 23"), "ok\r");
  // Manual: v 4000 and v 2012 after a pulse train on the inputs; the simulator has none.
  EXPECT_EQ(amp.values("g r0x3d").size(), 1u);
  EXPECT_EQ(amp.values("g r0x32").size(), 1u);
  EXPECT_EQ(amp.send("s r0xa9 0x00010001"), "ok\r");
  EXPECT_EQ(amp.send("s r0x24 0"), "ok\r");
}

TEST(CopleyTranscript, Section3_4_4_PulseAndDirection) {
  digital_position_transcript("0", "0x00020001");
}

TEST(CopleyTranscript, Section3_4_5_UpDown) {
  digital_position_transcript("256", "0x000f0001");
}

TEST(CopleyTranscript, Section3_4_6_Quadrature) {
  digital_position_transcript("512", "0x00010001");
}

TEST(CopleyTranscript, Section3_4_4To6_RatioText) {
  CopleyBench amp;
  EXPECT_EQ(amp.send("s r0xa9 0x000a0001"), "ok\r");
  EXPECT_EQ(amp.value("g r0xa9"), 0x000a0001);
  EXPECT_EQ(amp.send("s r0xa9 0xfff60001"), "ok\r");
  EXPECT_EQ(amp.value("g r0xa9"), static_cast<std::int32_t>(0xfff60001u)) << "-10:1";
  // The misprint 0xffff60001 (§3.4.4, §3.4.6) has 36 bits and does not fit the variable.
  EXPECT_EQ(amp.send("s r0xa9 0xffff60001"), "e 10\r");
}

TEST(CopleyTranscript, Section3_4_7_Homing) {
  CopleyBench amp;
  const std::vector<Exchange> transcript = {
      {"s r0xc2 544", "ok\r"},    // next index, positive
      {"s r0xc4 40000", "ok\r"},  // slow velocity 4000 counts/s
      {"s r0xc6 1000", "ok\r"},   // home offset
      {"s r0x24 21", "ok\r"},    {"t 2", "ok\r"},
  };
  expect_replies(amp, transcript);
  EXPECT_NE(amp.value("g r0xc9", 0.1) & bit(13), 0) << "homing in progress";
  // Manual: v 20480, bits 12 and 14; bit 14 (aborted) is unexplained there (digest §10.18).
  // The simulator reports referenced (bit 12) alone.
  EXPECT_EQ(amp.send("g r0xc9", 3), "v 4096\r");
  EXPECT_EQ(amp.send("g r0x32", 3), "v 1000\r") << "the reference is now the home offset";
}

TEST(CopleyTranscript, Section4_6_Outputs) {
  CopleyBench amp;
  EXPECT_EQ(amp.send("s r0x72 258 0"), "ok\r");  // OUT3 program controlled
  EXPECT_EQ(amp.send("s r0x73 258 0"), "ok\r");  // OUT4 program controlled
  // Manual: v 10 (OUT2 and OUT4 active); outputs are inactive after power-up here.
  EXPECT_EQ(amp.values("g r0xab").size(), 1u);
  amp.send("s r0xab 8");  // OUT4 active, to reproduce the manual's starting point for OUT3/4
  EXPECT_EQ(amp.send("s r0xab 4"), "ok\r");
  EXPECT_EQ(amp.send("g r0xab"), "v 4\r") << "OUT3 active, OUT4 inactive";
}

}  // namespace
}  // namespace fieldgate::sim::copley::test
