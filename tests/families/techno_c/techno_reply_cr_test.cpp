// What may follow a reply on a Techno line. A C142 that ends its `@0P` reply with a CR sent a
// little after the digits (issue 26, item 3): the reply is complete only once every reading's
// trailing bytes have arrived or the byte gap has passed, so the CR is never read as the next
// request's answer. And the `2` a limit makes the controller send on its own during a
// lower-case motion, when it comes just after the answer to a position query (on a loaded host
// the reader finds both at once): the motion's error, not a garbled answer; without a motion
// running the same byte is something the line should not carry.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <functional>
#include <map>
#include <string>

#include "drivers/techno_c/techno_family.hpp"
#include "fake_line.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

class TechnoAfterTheReply : public ::testing::Test {
 protected:
  void SetUp() override {
    transport_.keep_order();
    transport_.set_far_end([this](std::string_view bytes) { hear(bytes); });
    std::string error;
    Model model;
    model.family = "techno-c";
    node_ = *family_.parse_address("0", error);
    family_.configure_node(node_, model);
    test::run(io_, family_.on_link_open(link_, timing_));
  }

  // A scripted controller: `0` to every command; P answers as answer_position says.
  void hear(std::string_view bytes) {
    pending_.append(bytes);
    for (auto end = pending_.find('\r'); end != std::string::npos; end = pending_.find('\r')) {
      const std::string line = pending_.substr(0, end);
      pending_.erase(0, end + 1);
      if (line.ends_with("P"))
        answer_position();
      else
        transport_.deliver("0");
    }
  }

  Reply transact(std::string command, Request::Expect expect = Request::Expect::values) {
    return test::run(
        io_, family_.transact(link_, node_,
                              Request{std::move(command), expect, NumberFormat::decimal}, timing_));
  }

  asio::io_context io_;
  test::FakeLine transport_{io_, "techno-late-cr", 0};
  Link link_{transport_};
  TechnoFamily family_;
  NodeAddress node_;
  // A byte gap far longer than the CR's delay, so that the reading does not depend on load.
  LinkTiming timing_{1000ms, 200ms};
  std::string pending_;
  std::function<void()> answer_position;
};

TEST_F(TechnoAfterTheReply, TheCrAfterAPositionReplyIsNotTheNextAnswer) {
  int x = 1;
  // The next position in ack mode; its CR comes 5 ms later.
  answer_position = [&] {
    transport_.deliver(fmt::format("0{:06X}000000000000", x++));
    transport_.deliver("\r", 5ms);
  };
  for (int expected = 1; expected <= 3; ++expected) {
    const Reply reply = transact("P");
    ASSERT_EQ(reply.status, Reply::Status::ok) << reply.text;
    ASSERT_FALSE(reply.values.empty());
    EXPECT_EQ(reply.values[0], expected);
  }
}

// X = 574, and 2 ms after that answer, once, the `2` of a limit.
void answer_then_limit(test::FakeLine& line, bool& limit) {
  line.deliver(fmt::format("0{:06X}000000000000\r", 574));
  if (std::exchange(limit, false)) line.deliver("2", 2ms);
}

TEST_F(TechnoAfterTheReply, AnErrorRightAfterAPositionReplyEndsTheRunningMotion) {
  bool limit = false;
  answer_position = [&] { answer_then_limit(transport_, limit); };
  ASSERT_EQ(transact("a1000,2500", Request::Expect::ack).status, Reply::Status::ok);
  limit = true;
  const Reply during = transact("P");
  ASSERT_EQ(during.status, Reply::Status::ok) << during.text;
  EXPECT_EQ(during.values[0], 574);
  ASSERT_GE(during.values.size(), 9u);
  // The answer was sampled while the axis moved; the error is the next poll's news, as when it
  // comes a moment later (a quiet host reads it before the next request).
  EXPECT_EQ(during.values[8], 0);
  const Reply after = transact("P");
  ASSERT_EQ(after.status, Reply::Status::ok) << after.text;
  EXPECT_EQ(after.values[3], 0) << "the motion is over";
  EXPECT_EQ(after.values[7], 1) << "it ended with an error";
  EXPECT_EQ(after.values[8], '2');
}

TEST_F(TechnoAfterTheReply, WithoutAMotionTheSameByteIsGarbled) {
  bool limit = true;
  answer_position = [&] { answer_then_limit(transport_, limit); };
  const Reply r = transact("P");
  EXPECT_EQ(r.status, Reply::Status::garbled) << r.text;
}

}  // namespace
}  // namespace fieldgate
