// Link::discard_input before a request: what the OS holds is read off, counted and traced; the
// transport's flush runs only when the line is not known to be in step.
#include <gtest/gtest.h>

#include "held_bytes.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using test::kNoWait;
using test::read_now;

class LinkDiscard : public ::testing::Test {
 protected:
  LinkDiscard() {
    link_.set_tap([this](bool tx, std::string_view bytes) {
      if (!tx) traced_ += bytes;
    });
  }
  LinkRead read(const LinkTiming& timing = LinkTiming{50ms, 10ms}) {
    return read_now(link_, timing);
  }
  // A reply read whole: the line is in step. What it traced is forgotten.
  void answered(std::string reply = "v 1\r") {
    device_.held = std::move(reply);
    ASSERT_EQ(read().status, LinkRead::Status::frame);
    traced_.clear();
  }

  test::HeldBytes device_;
  Link link_{device_};
  std::string traced_;
};

TEST_F(LinkDiscard, AfterAWholeFrameAnEmptyQueueNeedsNoFlush) {
  ASSERT_NO_FATAL_FAILURE(answered());
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 0);
  EXPECT_EQ(link_.stats().bytes_discarded, 0u);
}

TEST_F(LinkDiscard, StraysInTheOsQueueAreCountedTracedAndFlushed) {
  ASSERT_NO_FATAL_FAILURE(answered());
  device_.held = "v 99\r";  // a late reply that came in after the frame was read
  link_.discard_input();
  EXPECT_EQ(traced_, "v 99\r");
  EXPECT_EQ(link_.stats().bytes_discarded, 5u);
  EXPECT_EQ(link_.stats().bytes_received, 9u);
  EXPECT_EQ(device_.flushes, 1) << "more may be on its way";
  device_.held = "v 2\r";
  const auto next = read();
  ASSERT_EQ(next.status, LinkRead::Status::frame);
  EXPECT_EQ(next.frame, "v 2\r");
}

TEST_F(LinkDiscard, BytesLeftBehindAFrameAreThrownAwayWithAFlush) {
  ASSERT_NO_FATAL_FAILURE(answered("v 1\rv 2"));
  link_.discard_input();
  EXPECT_EQ(traced_, "v 2");
  EXPECT_EQ(link_.buffered(), 0u);
  EXPECT_EQ(link_.stats().bytes_discarded, 3u);
  EXPECT_EQ(device_.flushes, 1);
}

TEST_F(LinkDiscard, AfterATimeoutTheQueueIsFlushedEvenWhenItLooksEmpty) {
  ASSERT_NO_FATAL_FAILURE(answered());
  ASSERT_EQ(read().status, LinkRead::Status::timeout);
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 1);
}

TEST_F(LinkDiscard, BeforeAnyFrameTheQueueIsFlushed) {
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 1) << "nothing has shown the line in step yet";
}

TEST_F(LinkDiscard, AfterAResyncTheQueueIsFlushedUntilAFrameComesAgain) {
  ASSERT_NO_FATAL_FAILURE(answered());  // a frame the family found garbled
  asio::io_context io;
  auto resync = asio::co_spawn(io, link_.resync(1ms, 100ms), asio::use_future);
  io.run();
  ASSERT_TRUE(resync.get().quiet);
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 1);
  ASSERT_NO_FATAL_FAILURE(answered("v 2\r"));
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 1) << "the new frame put the line back in step";
}

TEST_F(LinkDiscard, AFlushReadThatFindsNothingLeavesTheLineInStep) {
  ASSERT_NO_FATAL_FAILURE(answered());
  EXPECT_EQ(read(kNoWait).status, LinkRead::Status::timeout);
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 0);
}

TEST_F(LinkDiscard, AFrameAFlushReadFindsCameOutOfTurn) {
  ASSERT_NO_FATAL_FAILURE(answered());
  device_.held = "v 7\r";  // a late reply, taken by the flush before the next request
  const auto stray = read(kNoWait);
  ASSERT_EQ(stray.status, LinkRead::Status::frame);
  EXPECT_EQ(stray.frame, "v 7\r");
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 1) << "the rest of a backlog may be on its way";
}

TEST_F(LinkDiscard, ADeviceThatNeverStopsIsCutShortByTheFlush) {
  ASSERT_NO_FATAL_FAILURE(answered());
  device_.chatter = true;
  link_.discard_input();
  EXPECT_EQ(device_.flushes, 1);
  EXPECT_GE(link_.stats().bytes_discarded, 4096u);
  EXPECT_LT(link_.stats().bytes_discarded, 4096u + 512u);
}

}  // namespace
}  // namespace fieldgate
