// A lower-case motion is acknowledged with `0` at its start; a limit that stops it later makes
// the controller send `2` on its own. When the limit comes just after the controller answered a
// position query, the `2` follows that answer within the byte gap (on a loaded host the reader
// finds both at once). It is the motion's error, not a garbled answer; without a motion running
// the same byte is still something the line should not carry.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <string>

#include "drivers/techno_c/techno_family.hpp"
#include "fake_line.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

class TechnoTrailingMotionError : public ::testing::Test {
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

  // A scripted controller: `0` to every command; P answers X = 574 and, once
  // limit_after_next_poll is set, sends `2` 2 ms after that answer.
  void hear(std::string_view bytes) {
    pending_.append(bytes);
    for (auto end = pending_.find('\r'); end != std::string::npos; end = pending_.find('\r')) {
      const std::string line = pending_.substr(0, end);
      pending_.erase(0, end + 1);
      if (line.ends_with("P")) {
        transport_.deliver(fmt::format("0{:06X}000000000000\r", 574));
        if (std::exchange(limit_after_next_poll_, false)) transport_.deliver("2", 2ms);
      } else {
        transport_.deliver("0");
      }
    }
  }

  Reply transact(std::string command, Request::Expect expect) {
    return test::run(
        io_, family_.transact(link_, node_,
                              Request{std::move(command), expect, NumberFormat::decimal}, timing_));
  }

  asio::io_context io_;
  test::FakeLine transport_{io_, "techno-trailing-error", 0};
  Link link_{transport_};
  TechnoFamily family_;
  NodeAddress node_;
  // A byte gap far longer than the 2 ms, so that the reading does not depend on load.
  LinkTiming timing_{1000ms, 200ms};
  std::string pending_;
  bool limit_after_next_poll_ = false;
};

TEST_F(TechnoTrailingMotionError, AnErrorRightAfterAPositionReplyEndsTheRunningMotion) {
  ASSERT_EQ(transact("a1000,2500", Request::Expect::ack).status, Reply::Status::ok);
  limit_after_next_poll_ = true;
  const Reply during = transact("P", Request::Expect::values);
  ASSERT_EQ(during.status, Reply::Status::ok) << during.text;
  EXPECT_EQ(during.values[0], 574);
  ASSERT_GE(during.values.size(), 9u);
  // The answer was sampled while the axis moved; the error is the next poll's news, as when it
  // comes a moment later (a quiet host reads it before the next request).
  EXPECT_EQ(during.values[8], 0);
  const Reply after = transact("P", Request::Expect::values);
  ASSERT_EQ(after.status, Reply::Status::ok) << after.text;
  EXPECT_EQ(after.values[3], 0) << "the motion is over";
  EXPECT_EQ(after.values[7], 1) << "it ended with an error";
  EXPECT_EQ(after.values[8], '2');
}

TEST_F(TechnoTrailingMotionError, WithoutAMotionTheSameByteIsGarbled) {
  limit_after_next_poll_ = true;
  const Reply r = transact("P", Request::Expect::values);
  EXPECT_EQ(r.status, Reply::Status::garbled) << r.text;
}

}  // namespace
}  // namespace fieldgate
