// NodeSupervision on its own, with frames and times written out in the order they arrive: node
// guarding against heartbeats (the toggle bit, heartbeats another tool turned on) and the
// boot-up that makes a request sent before it a lost one (issue 49).
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "drivers/canopen/node_supervision.hpp"

namespace fieldgate::canopen {
namespace {

using namespace std::chrono_literals;

class FakeHost final : public NodeHost {
 public:
  Presence presence() const override { return presence_; }
  void go_online() override { presence_ = Presence::online; }
  void go_offline(std::string why) override {
    presence_ = Presence::offline;
    offline_why.push_back(std::move(why));
  }
  void probe_by(TimePoint) override {}
  void refresh_local_points(TimePoint) override {}
  void nmt_state_forgotten() override { ++forgotten; }
  void device_error(uint16_t, std::string) override {}
  void error_text(std::string) override {}
  void wake_worker() override {}
  void log(int, std::string text) override { logs.push_back(std::move(text)); }
  TimePoint now() const override { return now_; }

  bool logged(const std::string& text) const {
    return std::find(logs.begin(), logs.end(), text) != logs.end();
  }

  Presence presence_ = Presence::online;
  TimePoint now_{};
  std::vector<std::string> offline_why;
  std::vector<std::string> logs;
  int forgotten = 0;
};

class NodeSupervisionTest : public ::testing::Test {
 protected:
  static SupervisionTiming timing() {
    SupervisionTiming t;
    t.heartbeat_timeout = 300ms;  // producer time 100 ms: guarding every 100 ms
    t.reply_timeout = 50ms;
    t.offline_after = 2;
    return t;
  }

  // Brought up, its 0x1017 write refused at t0: watched by SDO, guarded from t0 on.
  void guarded_from_t0() {
    nmt_.bring_up(false);
    ASSERT_EQ(nmt_.duty(true), NodeSupervision::Duty::configure);
    nmt_.configured(Reply::of(Reply::Status::device_error, "SDO abort 0x06020000"), 100, t0_);
    ASSERT_EQ(nmt_.duty(true), NodeSupervision::Duty::guard);
    ASSERT_EQ(nmt_.next_guard(), t0_);
  }

  // The guard RTR, sent at `at` (it must be due).
  void rtr(TimePoint at) {
    ASSERT_LE(nmt_.next_guard(), at);
    const auto frame = nmt_.guard(at);
    ASSERT_TRUE(frame);
    EXPECT_EQ(to_string(*frame), "702#R");
    EXPECT_EQ(nmt_.next_guard(), at + 100ms);
  }

  // A state frame, as the byte on 0x702 (0x85: operational with the toggle bit).
  void state_frame(uint8_t byte, TimePoint at) {
    host_.now_ = at;
    nmt_.on_heartbeat(static_cast<uint8_t>(byte & 0x7F), (byte & 0x80) != 0, at);
  }

  TimePoint t0_ = TimePoint{} + 1h;
  FakeHost host_;
  NodeSupervision nmt_{2, "dev", timing(), host_};
};

// The device's plain heartbeats (0x05, 0x05, ...) are no guard replies, even where one answers
// an RTR: guarding stops once they come, and starts again when none came for a consumer time.
TEST_F(NodeSupervisionTest, HeartbeatsAreNoGuardRepliesAndStopGuarding) {
  guarded_from_t0();
  rtr(t0_);
  state_frame(0x05, t0_ + 40ms);  // first frame, toggle unknown: could be either
  rtr(t0_ + 100ms);
  state_frame(0x05, t0_ + 140ms);  // toggle 0 again where a reply had to carry 1: a heartbeat
  EXPECT_EQ(nmt_.status().guard_replies, 0u);
  EXPECT_TRUE(host_.logged(
      "node dev (2) sends heartbeats the gateway did not set up: node guarding stops while they "
      "come"));
  // No RTR while the heartbeat comes; none later than a consumer time after the last one.
  EXPECT_EQ(nmt_.next_guard(), t0_ + 440ms);
  for (auto at = t0_ + 240ms; at < t0_ + 1s; at += 100ms) {
    state_frame(0x05, at);
    EXPECT_EQ(nmt_.next_guard(), at + 300ms);
  }
  EXPECT_EQ(nmt_.status().guard_replies, 0u);
  EXPECT_EQ(nmt_.status().nmt_state, nmt_state::operational);
  EXPECT_EQ(nmt_.status().liveness, Liveness::sdo);  // it is not the gateway's heartbeat
  // The heartbeat stops (the other tool set 0x1017 = 0): guarding again.
  const auto resume = t0_ + 1240ms;
  EXPECT_EQ(nmt_.next_guard(), resume);
  rtr(resume);
  EXPECT_TRUE(host_.logged("node dev (2) sent no heartbeat within 300 ms: node guarding again"));
  // A device that does not guard: given up on after a consumer time, not kept alive by the
  // heartbeats it sent before.
  rtr(resume + 100ms);
  rtr(resume + 200ms);
  EXPECT_FALSE(nmt_.guard(resume + 300ms));
  EXPECT_EQ(nmt_.next_guard(), TimePoint::max());
  EXPECT_EQ(host_.forgotten, 1);
}

// After a boot-up the first guard reply carries 0, as a heartbeat does: a device that answers
// each RTR with its plain heartbeat (0x05, 0x05) has none of its frames taken as a reply.
TEST_F(NodeSupervisionTest, HeartbeatAfterBootUpIsNoGuardReply) {
  state_frame(0x00, t0_ - 10ms);
  guarded_from_t0();
  rtr(t0_);
  state_frame(0x05, t0_ + 5ms);
  EXPECT_EQ(nmt_.status().guard_replies, 0u);
  rtr(t0_ + 100ms);
  state_frame(0x05, t0_ + 105ms);
  EXPECT_EQ(nmt_.status().guard_replies, 0u);
  EXPECT_EQ(nmt_.next_guard(), t0_ + 405ms);  // a heartbeat: guarding waits
}

// A heartbeat between the RTRs of a guarded node that answers them: its replies count, and the
// heartbeat (no RTR outstanding) stops guarding.
TEST_F(NodeSupervisionTest, HeartbeatBetweenGuardRepliesStopsGuarding) {
  state_frame(0x00, t0_ - 10ms);  // boot-up: its first guard reply carries toggle 0
  guarded_from_t0();
  rtr(t0_);
  state_frame(0x7F, t0_ + 5ms);  // tells the toggle
  rtr(t0_ + 100ms);
  state_frame(0xFF, t0_ + 105ms);
  rtr(t0_ + 200ms);
  state_frame(0x7F, t0_ + 205ms);
  EXPECT_EQ(nmt_.status().guard_replies, 2u);
  state_frame(0x7F, t0_ + 250ms);  // nothing asked for it
  EXPECT_EQ(nmt_.status().guard_replies, 2u);
  EXPECT_EQ(nmt_.next_guard(), t0_ + 550ms);
}

// A node that guards and sends no heartbeat: replies alternate 0, 1, 0, ... and every one after
// the first is taken; guarding goes on.
TEST_F(NodeSupervisionTest, AlternatingGuardRepliesAreTaken) {
  state_frame(0x00, t0_ - 10ms);
  guarded_from_t0();
  const uint8_t replies[] = {0x7F, 0x85, 0x05, 0x85, 0x05};
  auto at = t0_;
  for (const auto reply : replies) {
    rtr(at);
    state_frame(reply, at + 3ms);
    at += 100ms;
  }
  EXPECT_EQ(nmt_.status().guard_replies, 4u);
  EXPECT_EQ(nmt_.next_guard(), at);  // still guarding
  EXPECT_TRUE(nmt_.guard(at + 300ms));
  EXPECT_EQ(host_.forgotten, 0);
}

// Guarding a node whose boot-up the gateway did not see: its toggle is learnt from its first
// reply, which alone is not counted; a reply out of step (1 where 0 was due) is followed.
TEST_F(NodeSupervisionTest, ToggleIsLearntWhereTheBootUpWasNotSeen) {
  guarded_from_t0();
  rtr(t0_);
  state_frame(0x85, t0_ + 3ms);  // toggle 1: a guard reply; the next carries 0
  EXPECT_EQ(nmt_.status().guard_replies, 0u);
  rtr(t0_ + 100ms);
  state_frame(0x05, t0_ + 103ms);
  EXPECT_EQ(nmt_.status().guard_replies, 1u);
  rtr(t0_ + 200ms);
  state_frame(0x05, t0_ + 203ms);  // 0 where 1 was due: a heartbeat, not a reply
  EXPECT_EQ(nmt_.status().guard_replies, 1u);
  EXPECT_EQ(nmt_.next_guard(), t0_ + 503ms);  // guarding waits for the heartbeat
}

// A guard reply with the toggle bit set is never a heartbeat, even where none was asked for
// (another master guards the node too).
TEST_F(NodeSupervisionTest, ToggledFrameWithoutRtrIsNoHeartbeat) {
  state_frame(0x00, t0_ - 10ms);
  guarded_from_t0();
  rtr(t0_);
  state_frame(0x05, t0_ + 3ms);   // tells the toggle: 1 next
  state_frame(0x85, t0_ + 50ms);  // answers someone else's RTR
  EXPECT_EQ(nmt_.status().guard_replies, 0u);
  EXPECT_EQ(nmt_.next_guard(), t0_ + 100ms);  // still guarding
  // Followed: the device's next reply carries 0 again, and is taken.
  rtr(t0_ + 100ms);
  state_frame(0x05, t0_ + 103ms);
  EXPECT_EQ(nmt_.status().guard_replies, 1u);
  EXPECT_EQ(nmt_.next_guard(), t0_ + 200ms);
}

// A boot-up after a request went out: the request was lost to the restart. Literal order: the
// request at t0, the boot-up at t0 + 20 ms, its timeout at t0 + 50 ms.
TEST_F(NodeSupervisionTest, RequestSentBeforeTheBootUpIsLostToIt) {
  const auto sent = t0_;
  EXPECT_FALSE(nmt_.restarted_since(sent));
  state_frame(0x00, t0_ + 20ms);
  EXPECT_TRUE(nmt_.restarted_since(sent));
  EXPECT_TRUE(nmt_.restarted_since(t0_ + 19ms));
  // Sent at or after the boot-up: its timeout is the node's own silence.
  EXPECT_FALSE(nmt_.restarted_since(t0_ + 20ms));
  EXPECT_FALSE(nmt_.restarted_since(t0_ + 30ms));
  // Heartbeats after the boot-up do not move it.
  state_frame(0x7F, t0_ + 40ms);
  EXPECT_TRUE(nmt_.restarted_since(sent));
}

}  // namespace
}  // namespace fieldgate::canopen
