// Link::discard_input before a request: what the OS holds is read off, counted and traced; the
// transport's flush runs only when the line is not known to be in step.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/use_future.hpp>

#include <algorithm>
#include <cstring>

#include "drivers/link.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

// The OS's input queue (`held`), handed out by read_available and by reads; a device that
// never stops (`chatter`) refills it on every read. Flushes are counted.
class QueuedInput final : public ByteTransport {
 public:
  std::string held;
  bool chatter = false;
  int flushes = 0;

  asio::awaitable<std::error_code> open() override { co_return std::error_code{}; }
  void close() override {}
  bool is_open() const override { return true; }
  asio::awaitable<std::error_code> write(std::string_view) override { co_return std::error_code{}; }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    asio::steady_timer tick(co_await asio::this_coro::executor);
    while (held.empty() && !chatter) {
      tick.expires_after(1ms);
      co_await tick.async_wait(asio::use_awaitable);
    }
    co_return std::pair{std::error_code{}, read_available(buffer)};
  }
  std::size_t read_available(asio::mutable_buffer buffer) override {
    if (chatter) held = "garbage ";
    const std::size_t n = std::min(buffer.size(), held.size());
    std::memcpy(buffer.data(), held.data(), n);
    held.erase(0, n);
    return n;
  }
  void discard_input() override {
    ++flushes;
    held.clear();
    chatter = false;
  }
  std::string describe() const override { return "queued input"; }
  double char_time_us() const override { return 0; }
};

const FrameSplitter kLine = [](std::string_view b) -> std::size_t {
  const auto p = b.find('\r');
  return p == std::string_view::npos ? 0 : p + 1;
};

LinkRead read_one(Link& link, const LinkTiming& timing = LinkTiming{50ms, 10ms}) {
  asio::io_context io;
  auto read = asio::co_spawn(io, link.read_frame(kLine, timing), asio::use_future);
  io.run();
  return read.get();
}

const LinkTiming kNoWait{0us, 0us};

struct Traced {
  std::string rx;
  explicit Traced(Link& link) {
    link.set_tap([this](bool tx, std::string_view bytes) {
      if (!tx) rx += bytes;
    });
  }
};

TEST(LinkDiscard, AfterAWholeFrameAnEmptyQueueNeedsNoFlush) {
  QueuedInput device;
  device.held = "v 1\r";
  Link link(device);
  ASSERT_EQ(read_one(link).status, LinkRead::Status::frame);
  link.discard_input();
  EXPECT_EQ(device.flushes, 0);
  EXPECT_EQ(link.stats().bytes_discarded, 0u);
}

TEST(LinkDiscard, StraysInTheOsQueueAreCountedTracedAndFlushed) {
  QueuedInput device;
  device.held = "v 1\r";
  Link link(device);
  ASSERT_EQ(read_one(link).status, LinkRead::Status::frame);
  Traced traced(link);
  device.held = "v 99\r";  // a late reply that came in after the frame was read
  link.discard_input();
  EXPECT_EQ(traced.rx, "v 99\r");
  EXPECT_EQ(link.stats().bytes_discarded, 5u);
  EXPECT_EQ(link.stats().bytes_received, 9u);
  EXPECT_EQ(device.flushes, 1) << "more may be on its way";
  device.held = "v 2\r";
  const auto next = read_one(link);
  ASSERT_EQ(next.status, LinkRead::Status::frame);
  EXPECT_EQ(next.frame, "v 2\r");
}

TEST(LinkDiscard, BytesLeftBehindAFrameAreThrownAwayWithAFlush) {
  QueuedInput device;
  device.held = "v 1\rv 2";
  Link link(device);
  ASSERT_EQ(read_one(link).status, LinkRead::Status::frame);
  Traced traced(link);
  link.discard_input();
  EXPECT_EQ(traced.rx, "v 2");
  EXPECT_EQ(link.buffered(), 0u);
  EXPECT_EQ(link.stats().bytes_discarded, 3u);
  EXPECT_EQ(device.flushes, 1);
}

TEST(LinkDiscard, AfterATimeoutTheQueueIsFlushedEvenWhenItLooksEmpty) {
  QueuedInput device;
  Link link(device);
  ASSERT_EQ(read_one(link).status, LinkRead::Status::timeout);
  link.discard_input();
  EXPECT_EQ(device.flushes, 1);
}

TEST(LinkDiscard, BeforeAnyFrameTheQueueIsFlushed) {
  QueuedInput device;
  Link link(device);
  link.discard_input();
  EXPECT_EQ(device.flushes, 1) << "nothing has shown the line in step yet";
}

TEST(LinkDiscard, AfterAResyncTheQueueIsFlushedUntilAFrameComesAgain) {
  QueuedInput device;
  device.held = "v 1\r";
  Link link(device);
  ASSERT_EQ(read_one(link).status, LinkRead::Status::frame);  // a frame the family found garbled
  asio::io_context io;
  auto resync = asio::co_spawn(io, link.resync(1ms, 100ms), asio::use_future);
  io.run();
  ASSERT_TRUE(resync.get().quiet);
  link.discard_input();
  EXPECT_EQ(device.flushes, 1);
  device.held = "v 2\r";
  ASSERT_EQ(read_one(link).status, LinkRead::Status::frame);
  link.discard_input();
  EXPECT_EQ(device.flushes, 1) << "the new frame put the line back in step";
}

TEST(LinkDiscard, AFlushReadThatFindsNothingLeavesTheLineInStep) {
  QueuedInput device;
  device.held = "v 1\r";
  Link link(device);
  ASSERT_EQ(read_one(link).status, LinkRead::Status::frame);
  EXPECT_EQ(read_one(link, kNoWait).status, LinkRead::Status::timeout);
  link.discard_input();
  EXPECT_EQ(device.flushes, 0);
}

TEST(LinkDiscard, AFrameAFlushReadFindsCameOutOfTurn) {
  QueuedInput device;
  device.held = "v 1\r";
  Link link(device);
  ASSERT_EQ(read_one(link).status, LinkRead::Status::frame);
  device.held = "v 7\r";  // a late reply, taken by the flush before the next request
  const auto stray = read_one(link, kNoWait);
  ASSERT_EQ(stray.status, LinkRead::Status::frame);
  EXPECT_EQ(stray.frame, "v 7\r");
  link.discard_input();
  EXPECT_EQ(device.flushes, 1) << "the rest of a backlog may be on its way";
}

TEST(LinkDiscard, ADeviceThatNeverStopsIsCutShortByTheFlush) {
  QueuedInput device;
  device.held = "v 1\r";
  Link link(device);
  ASSERT_EQ(read_one(link).status, LinkRead::Status::frame);
  device.chatter = true;
  link.discard_input();
  EXPECT_EQ(device.flushes, 1);
  EXPECT_GE(link.stats().bytes_discarded, 4096u);
  EXPECT_LT(link.stats().bytes_discarded, 4096u + 512u);
}

}  // namespace
}  // namespace fieldgate
