// Link::send_ahead: the next exchange's request written the moment the reply before it was
// accepted, then taken over by that exchange's own send(). Nothing written twice, nothing of its
// reply thrown away, and an exchange that asks for other bytes fails instead of sending them.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

#include <vector>

#include "held_bytes.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using test::kNoWait;
using test::read_now;

class LinkSendAhead : public ::testing::Test {
 protected:
  LinkSendAhead() {
    link_.set_tap([this](bool tx, std::string_view bytes) {
      (tx ? traced_tx_ : traced_rx_) += std::string(bytes) + "|";
      if (tx) tx_times_.push_back(link_.tap_time());
    });
  }
  std::error_code send(std::string_view bytes) {
    asio::io_context io;
    auto sent = asio::co_spawn(io, link_.send(bytes), asio::use_future);
    io.run();
    return sent.get();
  }

  test::HeldBytes device_;
  Link link_{device_};
  std::string traced_tx_, traced_rx_;
  std::vector<std::chrono::steady_clock::time_point> tx_times_;
};

TEST_F(LinkSendAhead, TheRequestGoesOutAtOnceAndItsExchangeTakesItOver) {
  ASSERT_TRUE(link_.send_ahead("g r0x32\r"));
  EXPECT_EQ(device_.written, "g r0x32\r");
  EXPECT_EQ(link_.stats().bytes_sent, 8u);
  EXPECT_TRUE(link_.has_sent_ahead());
  EXPECT_EQ(traced_tx_, "") << "traced when its exchange begins";

  link_.take_over_sent_ahead();
  EXPECT_FALSE(send("g r0x32\r"));
  EXPECT_EQ(device_.written, "g r0x32\r") << "not written twice";
  EXPECT_EQ(link_.stats().bytes_sent, 8u);
  EXPECT_EQ(traced_tx_, "g r0x32\r|");
  ASSERT_EQ(tx_times_.size(), 1u);
  EXPECT_EQ(tx_times_[0], link_.sent_ahead_at()) << "stamped with when it was written";
  EXPECT_FALSE(link_.has_sent_ahead());
  EXPECT_FALSE(link_.take_ahead_mismatch());

  EXPECT_FALSE(send("g r0x33\r")) << "the exchange after it sends as always";
  EXPECT_EQ(device_.written, "g r0x32\rg r0x33\r");
}

TEST_F(LinkSendAhead, ItsReplyIsNotThrownAwayBeforeTheExchangeReadsIt) {
  ASSERT_TRUE(link_.send_ahead("g r0x32\r"));
  device_.held = "v 12";  // the reply's first bytes, already in the OS queue
  link_.take_over_sent_ahead();
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 0);
  EXPECT_EQ(link_.stats().bytes_discarded, 0u);
  const auto flush = read_now(link_, kNoWait);
  EXPECT_EQ(flush.status, LinkRead::Status::timeout);
  EXPECT_EQ(flush.partial, "");
  EXPECT_EQ(device_.held, "v 12") << "a read that may not wait leaves the reply alone";
  ASSERT_FALSE(send("g r0x32\r"));
  device_.held += "3\r";
  const auto reply = read_now(link_, LinkTiming{50ms, 10ms});
  ASSERT_EQ(reply.status, LinkRead::Status::frame);
  EXPECT_EQ(reply.frame, "v 123\r");
}

TEST_F(LinkSendAhead, AnExchangeThatAsksForOtherBytesFailsAndSendsNothing) {
  ASSERT_TRUE(link_.send_ahead("g r0x32\r"));
  link_.take_over_sent_ahead();
  const auto ec = send("s r0x24 21\r");
  EXPECT_EQ(ec, std::make_error_code(std::errc::protocol_error));
  EXPECT_EQ(device_.written, "g r0x32\r");
  EXPECT_TRUE(link_.take_ahead_mismatch());
  EXPECT_FALSE(link_.take_ahead_mismatch()) << "said once";
  EXPECT_FALSE(link_.has_sent_ahead());
  EXPECT_EQ(traced_tx_, "g r0x32\r|") << "what went out is traced all the same";
}

TEST_F(LinkSendAhead, AnUrgentSendMeanwhileGoesOutAndLeavesItSentAhead) {
  ASSERT_TRUE(link_.send_ahead("g r0x32\r"));
  EXPECT_FALSE(send("\x1b"));
  EXPECT_EQ(device_.written, "g r0x32\r\x1b");
  EXPECT_TRUE(link_.has_sent_ahead());
  link_.take_over_sent_ahead();
  EXPECT_FALSE(send("g r0x32\r"));
  EXPECT_EQ(device_.written, "g r0x32\r\x1b");
}

TEST_F(LinkSendAhead, NothingIsSentAheadWhereTheTransportWouldWait) {
  device_.takes_at_once = 0;
  EXPECT_FALSE(link_.send_ahead("g r0x32\r"));
  EXPECT_FALSE(link_.has_sent_ahead());
  EXPECT_EQ(link_.stats().bytes_sent, 0u);
  link_.take_over_sent_ahead();  // nothing to take over: the next send is an ordinary one
  EXPECT_FALSE(send("g r0x32\r"));
  EXPECT_EQ(device_.written, "g r0x32\r");
  EXPECT_FALSE(link_.take_ahead_mismatch());
}

TEST_F(LinkSendAhead, APartWrittenAheadIsFinishedByItsExchange) {
  device_.takes_at_once = 3;
  ASSERT_TRUE(link_.send_ahead("g r0x32\r"));
  EXPECT_EQ(device_.written, "g r");
  EXPECT_EQ(link_.stats().bytes_sent, 3u);
  link_.take_over_sent_ahead();
  device_.takes_at_once = static_cast<std::size_t>(-1);
  EXPECT_FALSE(send("g r0x32\r"));
  EXPECT_EQ(device_.written, "g r0x32\r");
  EXPECT_EQ(link_.stats().bytes_sent, 8u);
}

TEST_F(LinkSendAhead, OnlyOneRequestIsAheadAtATime) {
  ASSERT_TRUE(link_.send_ahead("g r0x32\r"));
  EXPECT_FALSE(link_.send_ahead("g r0x33\r"));
  EXPECT_EQ(device_.written, "g r0x32\r");
}

TEST_F(LinkSendAhead, ARequestGivenUpIsTracedAndForgotten) {
  ASSERT_TRUE(link_.send_ahead("g r0x32\r"));
  link_.drop_sent_ahead();
  EXPECT_FALSE(link_.has_sent_ahead());
  EXPECT_EQ(traced_tx_, "g r0x32\r|");
  device_.held = "v 1\r";
  link_.discard_input();
  EXPECT_EQ(link_.stats().bytes_discarded, 4u) << "strays are read off again";
}

}  // namespace
}  // namespace fieldgate
