// Link::resync: after a failed exchange the line is drained until quiet for the guard time, so
// a late reply cannot answer the next request.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/use_future.hpp>

#include <cstring>
#include <deque>

#include "drivers/link.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// A device that answers every line with "r<n>\r" after `delay`.
class SlowDevice final : public ByteTransport {
 public:
  explicit SlowDevice(std::chrono::milliseconds delay) : delay_(delay) {}
  asio::awaitable<std::error_code> open() override { co_return std::error_code{}; }
  void close() override {}
  bool is_open() const override { return true; }
  asio::awaitable<std::error_code> write(std::string_view) override {
    due_.push_back({Clock::now() + delay_, "r" + std::to_string(++count_) + "\r"});
    co_return std::error_code{};
  }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    asio::steady_timer t(co_await asio::this_coro::executor);
    for (;;) {
      if (const auto n = read_available(buffer); n > 0) co_return std::pair{std::error_code{}, n};
      t.expires_after(1ms);
      co_await t.async_wait(asio::use_awaitable);
    }
  }
  std::size_t read_available(asio::mutable_buffer buffer) override {
    if (due_.empty() || due_.front().first > Clock::now()) return 0;
    const std::string text = due_.front().second;
    due_.pop_front();
    std::memcpy(buffer.data(), text.data(), text.size());
    return text.size();
  }
  void discard_input() override {
    while (!due_.empty() && due_.front().first <= Clock::now()) due_.pop_front();
  }
  std::string describe() const override { return "slow device"; }
  double char_time_us() const override { return 0; }

 private:
  std::chrono::milliseconds delay_;
  int count_ = 0;
  std::deque<std::pair<Clock::time_point, std::string>> due_;
};

std::size_t line(std::string_view b) {
  const auto p = b.find('\r');
  return p == std::string_view::npos ? 0 : p + 1;
}

template <typename T>
T run(asio::io_context& io, asio::awaitable<T> a) {
  auto f = asio::co_spawn(io, std::move(a), asio::use_future);
  io.restart();
  io.run();
  return f.get();
}

TEST(LinkResync, DrainsTheLateReplySoTheNextRequestGetsItsOwn) {
  asio::io_context io;
  SlowDevice device(40ms);
  Link link(device);
  const LinkTiming timing{20ms, 5ms, 0us};
  auto exchange = [&]() -> asio::awaitable<LinkRead> {
    link.discard_input();
    co_await link.send("q\r");
    co_return co_await link.read_frame(line, timing);
  };
  EXPECT_EQ(run(io, exchange()).status, LinkRead::Status::timeout);
  const auto guard = guard_time(timing, 0);
  EXPECT_EQ(guard, 25ms);  // reply_timeout + byte_timeout (no character time on this link)
  const LinkResync found = run(io, link.resync(guard, 10 * guard));
  EXPECT_TRUE(found.quiet);
  EXPECT_EQ(found.drained, "r1\r");
  EXPECT_EQ(link.stats().resyncs, 1u);
  EXPECT_EQ(link.stats().resync_bytes, 3u);
  // Without the resync the late "r1" would have been taken as the second request's reply.
  const LinkTiming patient{60ms, 5ms, 0us};
  auto second = [&]() -> asio::awaitable<LinkRead> {
    link.discard_input();
    co_await link.send("q\r");
    co_return co_await link.read_frame(line, patient);
  };
  const auto read = run(io, second());
  ASSERT_EQ(read.status, LinkRead::Status::frame);
  EXPECT_EQ(read.frame, "r2\r");
}

TEST(LinkResync, AQuietLineCostsOneGuardTime) {
  asio::io_context io;
  SlowDevice device(1ms);
  Link link(device);
  const LinkResync found = run(io, link.resync(10ms, 100ms));
  EXPECT_TRUE(found.quiet);
  EXPECT_TRUE(found.drained.empty());
  EXPECT_GE(found.waited, 10ms);
}

TEST(LinkResync, DerivedGuardCoversCharacterTimes) {
  const LinkTiming timing{50ms, 10ms, 0us};
  // 9600 baud 8N1: 1041.7 us per character, 16 of them exceed byte_timeout.
  EXPECT_EQ(guard_time(timing, 1041.7), 50ms + 16667us);
  EXPECT_EQ(guard_time(timing, 86.8), 60ms);  // 115200: byte_timeout dominates
  const LinkTiming pinned{50ms, 10ms, 200ms};
  EXPECT_EQ(guard_time(pinned, 1041.7), 200ms);
}

}  // namespace
}  // namespace fieldgate
