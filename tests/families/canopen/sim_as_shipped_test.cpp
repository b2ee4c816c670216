// The CANopen simulator's power-up variants, frames in memory and injected time: a device as it
// ships (0x1017 = 0), one without 0x1017, one whose heartbeat producer never sends, and one
// that refuses NMT start while its error register is set.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>
#include <vector>

#include "network.hpp"

namespace fieldgate::sim::canopen {
namespace {

using namespace std::chrono_literals;

class Device {
 public:
  explicit Device(NodeConfig config)
      : net_(config, [this](const CanFrame& f) { out_.push_back(to_string(f)); }) {
    net_.add_node(2, now_);
  }
  void advance(Clock::duration d) {
    const TimePoint end = now_ + d;
    while (now_ < end) {
      now_ = std::min(end, std::max(now_ + 1ms, net_.next_deadline()));
      net_.advance(now_);
    }
  }
  void send(const std::string& text) { net_.receive(*parse_frame(text), now_); }
  std::vector<std::string> take() { return std::exchange(out_, {}); }
  // Sends a frame and takes what the device sent back.
  std::vector<std::string> answer(const std::string& text) {
    send(text);
    return take();
  }
  std::size_t count(const std::string& frame) const {
    return static_cast<std::size_t>(std::count(out_.begin(), out_.end(), frame));
  }
  Node& node() { return *net_.node(2); }

 private:
  TimePoint now_ = TimePoint{} + 1h;
  std::vector<std::string> out_;
  Network net_;
};

NodeConfig shipped() {
  NodeConfig c;
  c.heartbeat_ms = 0;
  return c;
}

TEST(SimAsShipped, NoHeartbeatUntilAMasterSets1017) {
  Device d(shipped());
  EXPECT_EQ(d.take(), std::vector<std::string>{"702#00"});  // boot-up only
  d.advance(3s);
  EXPECT_TRUE(d.take().empty());
  EXPECT_EQ(d.answer("602#4017100000000000"),
            std::vector<std::string>{"582#4B17100000000000"});  // 0x1017 = 0
  EXPECT_EQ(d.answer("602#2B17100064000000"),
            std::vector<std::string>{"582#6017100000000000"});  // 100 ms
  d.advance(1s);
  EXPECT_EQ(d.count("702#7F"), 10u);
}

TEST(SimAsShipped, WithoutHeartbeatObjectButGuarding) {
  auto c = shipped();
  c.heartbeat_object = HeartbeatObject::absent;
  Device d(c);
  d.take();
  EXPECT_EQ(d.answer("602#2B17100064000000"),
            std::vector<std::string>{"582#8017100000000206"});  // no such object
  EXPECT_EQ(d.answer("702#R"), std::vector<std::string>{"702#7F"});
  EXPECT_EQ(d.answer("702#R"), std::vector<std::string>{"702#FF"});  // toggle bit
}

TEST(SimAsShipped, SilentProducerTakesTheWriteAndSendsNothing) {
  auto c = shipped();
  c.heartbeat_object = HeartbeatObject::silent;
  Device d(c);
  d.take();
  EXPECT_EQ(d.answer("602#2B17100064000000"), std::vector<std::string>{"582#6017100000000000"});
  EXPECT_EQ(d.answer("602#4017100000000000"), std::vector<std::string>{"582#4B17100064000000"});
  d.advance(1s);
  EXPECT_TRUE(d.take().empty());
}

TEST(SimAsShipped, StaysPreOperationalWhileItsErrorRegisterIsSet) {
  auto c = shipped();
  c.power_up_error = 0x5000;
  c.start_needs_no_error = true;
  Device d(c);
  // Boot-up, then the EMCY of the error it powered up with.
  EXPECT_EQ(d.take(), (std::vector<std::string>{"702#00", "082#0050010000000000"}));
  EXPECT_EQ(d.node().error_register(), 0x01);
  d.send("000#0102");
  EXPECT_EQ(d.node().nmt_state(), NmtState::pre_operational);
  EXPECT_EQ(d.answer("602#4001100000000000"), std::vector<std::string>{"582#4F01100001000000"});
  // CiA 402 fault reset (rising edge of bit 7) clears it; then NMT start is carried out.
  d.advance(50ms);
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
  Device d(c);
  d.send("000#0102");
  EXPECT_EQ(d.node().nmt_state(), NmtState::operational);
}

}  // namespace
}  // namespace fieldgate::sim::canopen
