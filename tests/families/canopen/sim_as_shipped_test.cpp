// The CANopen simulator's power-up variants, frames in memory and injected time: a device as it
// ships (0x1017 = 0), one without 0x1017, one whose heartbeat producer never sends, and one
// that refuses NMT start while its error register is set.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <vector>

#include "sim_bus.hpp"

namespace fieldgate::sim::canopen {
namespace {

using namespace std::chrono_literals;

NodeConfig shipped() {
  return with_heartbeat_ms(0);
}

TEST(SimAsShipped, NoHeartbeatUntilAMasterSets1017) {
  SimBus d(shipped());
  EXPECT_EQ(d.take(), std::vector<std::string>{"702#00"});  // boot-up only
  d.advance_at_least_1ms_apart(3s);
  EXPECT_TRUE(d.take().empty());
  EXPECT_EQ(d.answer("602#4017100000000000"),
            std::vector<std::string>{"582#4B17100000000000"});  // 0x1017 = 0
  EXPECT_EQ(d.answer("602#2B17100064000000"),
            std::vector<std::string>{"582#6017100000000000"});  // 100 ms
  d.advance_at_least_1ms_apart(1s);
  EXPECT_EQ(d.count("702#7F"), 10u);
}

TEST(SimAsShipped, WithoutHeartbeatObjectButGuarding) {
  auto c = shipped();
  c.heartbeat_object = HeartbeatObject::absent;
  SimBus d(c);
  d.take();
  EXPECT_EQ(d.answer("602#2B17100064000000"),
            std::vector<std::string>{"582#8017100000000206"});  // no such object
  EXPECT_EQ(d.answer("702#R"), std::vector<std::string>{"702#7F"});
  EXPECT_EQ(d.answer("702#R"), std::vector<std::string>{"702#FF"});  // toggle bit
}

TEST(SimAsShipped, SilentProducerTakesTheWriteAndSendsNothing) {
  auto c = shipped();
  c.heartbeat_object = HeartbeatObject::silent;
  SimBus d(c);
  d.take();
  EXPECT_EQ(d.answer("602#2B17100064000000"), std::vector<std::string>{"582#6017100000000000"});
  EXPECT_EQ(d.answer("602#4017100000000000"), std::vector<std::string>{"582#4B17100064000000"});
  d.advance_at_least_1ms_apart(1s);
  EXPECT_TRUE(d.take().empty());
}

TEST(SimAsShipped, StaysPreOperationalWhileItsErrorRegisterIsSet) {
  auto c = shipped();
  c.power_up_error = 0x5000;
  c.start_needs_no_error = true;
  SimBus d(c);
  // Boot-up, then the EMCY of the error it powered up with.
  EXPECT_EQ(d.take(), (std::vector<std::string>{"702#00", "082#0050010000000000"}));
  EXPECT_EQ(d.node().error_register(), 0x01);
  d.send("000#0102");
  EXPECT_EQ(d.node().nmt_state(), NmtState::pre_operational);
  EXPECT_EQ(d.answer("602#4001100000000000"), std::vector<std::string>{"582#4F01100001000000"});
  // CiA 402 fault reset (rising edge of bit 7) clears it; then NMT start is carried out.
  d.advance_at_least_1ms_apart(50ms);
  d.send("602#2B40600000000000");
  d.send("602#2B40600080000000");
  d.take();
  EXPECT_EQ(d.node().error_register(), 0x00);
  d.send("000#0102");
  EXPECT_EQ(d.node().nmt_state(), NmtState::operational);
}

TEST(SimAsShipped, StartIsCarriedOutWithAnErrorUnlessTheSwitchIsSet) {
  auto c = shipped();
  c.power_up_error = 0x5000;
  SimBus d(c);
  d.send("000#0102");
  EXPECT_EQ(d.node().nmt_state(), NmtState::operational);
}

}  // namespace
}  // namespace fieldgate::sim::canopen
