// Link::read_frame with a deadline already passed (a family's flush before a request): it takes
// what the OS holds and ends, without starting a read or a timer on the event loop.
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

// Bytes the OS has buffered (`held`), handed out by read_available; an asynchronous read waits
// for bytes put in `later` and is counted.
class HeldBytes final : public ByteTransport {
 public:
  std::string held;
  std::string later;
  int reads_started = 0;

  asio::awaitable<std::error_code> open() override { co_return std::error_code{}; }
  void close() override {}
  bool is_open() const override { return true; }
  asio::awaitable<std::error_code> write(std::string_view) override { co_return std::error_code{}; }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    ++reads_started;
    asio::steady_timer tick(co_await asio::this_coro::executor);
    while (held.empty()) {
      held = std::exchange(later, {});
      tick.expires_after(1ms);
      co_await tick.async_wait(asio::use_awaitable);
    }
    co_return std::pair{std::error_code{}, read_available(buffer)};
  }
  std::size_t read_available(asio::mutable_buffer buffer) override {
    const std::size_t n = std::min(buffer.size(), held.size());
    std::memcpy(buffer.data(), held.data(), n);
    held.erase(0, n);
    return n;
  }
  void discard_input() override { held.clear(); }
  std::string describe() const override { return "held bytes"; }
  double char_time_us() const override { return 0; }
};

// read_frame keeps a reference to its splitter: it must outlive the read.
const FrameSplitter kLine = [](std::string_view b) -> std::size_t {
  const auto p = b.find('\r');
  return p == std::string_view::npos ? 0 : p + 1;
};

const LinkTiming kNoWait{0us, 0us};

LinkRead read_now(Link& link, const LinkTiming& timing) {
  asio::io_context io;
  auto read = asio::co_spawn(io, link.read_frame(kLine, timing), asio::use_future);
  io.run();
  return read.get();
}

TEST(LinkNoWait, TakesAWholeFrameTheOsHolds) {
  HeldBytes device;
  device.held = "v 1\rv 2\r";
  Link link(device);
  const auto read = read_now(link, kNoWait);
  ASSERT_EQ(read.status, LinkRead::Status::frame);
  EXPECT_EQ(read.frame, "v 1\r");
  EXPECT_EQ(link.buffered_bytes(), "v 2\r") << "the rest stays for the next read";
  EXPECT_EQ(device.reads_started, 0);
  EXPECT_EQ(link.stats().bytes_received, 8u);
}

TEST(LinkNoWait, EndsAtOnceWhenNothingIsThereAndTheNextReadWaits) {
  HeldBytes device;
  Link link(device);
  const auto nothing = read_now(link, kNoWait);
  EXPECT_EQ(nothing.status, LinkRead::Status::timeout);
  EXPECT_TRUE(nothing.partial.empty());
  EXPECT_EQ(device.reads_started, 0) << "no read was started that could take a later byte";

  device.later = "v 3\r";
  const auto waited = read_now(link, LinkTiming{200ms, 20ms});
  ASSERT_EQ(waited.status, LinkRead::Status::frame);
  EXPECT_EQ(waited.frame, "v 3\r");
  EXPECT_EQ(device.reads_started, 1);
}

TEST(LinkNoWait, AnIncompleteFrameIsAPartialTimeoutAndIsTraced) {
  HeldBytes device;
  device.held = "v 4";
  Link link(device);
  std::string traced;
  link.set_tap([&](bool tx, std::string_view bytes) {
    if (!tx) traced += bytes;
  });
  const auto read = read_now(link, kNoWait);
  EXPECT_EQ(read.status, LinkRead::Status::timeout);
  EXPECT_EQ(read.partial, "v 4");
  EXPECT_EQ(traced, "v 4");
  EXPECT_EQ(link.buffered(), 0u);
  EXPECT_EQ(device.reads_started, 0);
}

}  // namespace
}  // namespace fieldgate
