// ByteTransport::read_some_until: a read that ends at a deadline takes no byte, and what arrives
// later is read next. Run on a stream transport (TcpTransport over loopback, the override with
// one timer) and on the default that races read_some() against a timer.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/use_future.hpp>
#include <boost/asio/write.hpp>

#include <cstring>
#include <string>
#include <thread>

#include "drivers/transport/tcp_transport.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using tcp = asio::ip::tcp;

// A loopback peer: the transport under test connects to it, the test writes through `peer`.
struct LoopbackPair {
  asio::io_context io;
  tcp::acceptor acceptor{io, tcp::endpoint(asio::ip::address_v4::loopback(), 0)};
  tcp::socket peer{io};
  TcpTransport transport{io.get_executor(), "127.0.0.1", acceptor.local_endpoint().port(), 0};

  LoopbackPair() {
    acceptor.async_accept(peer, [](const boost::system::error_code& ec) { ASSERT_FALSE(ec); });
    auto opened = asio::co_spawn(io, transport.open(), asio::use_future);
    io.run();
    io.restart();
    EXPECT_FALSE(opened.get());
  }

  template <typename Body>
  auto run(Body body) {
    auto done = asio::co_spawn(io, body(), asio::use_future);
    io.run();
    io.restart();
    return done.get();
  }

  void send(const std::string& text) { asio::write(peer, asio::buffer(text)); }

  // One read_some_until: its error and the bytes it took.
  asio::awaitable<std::pair<std::error_code, std::string>> read(Clock::time_point deadline) {
    char chunk[64];
    auto [ec, n] = co_await transport.read_some_until(asio::buffer(chunk), deadline);
    co_return std::pair{ec, std::string(chunk, n)};
  }
};

TEST(ReadDeadline, BytesThatArriveBeforeTheDeadlineAreReturned) {
  LoopbackPair pair;
  pair.send("1TS000033\r\n");
  const std::pair<std::error_code, std::string> whole_reply{std::error_code{}, "1TS000033\r\n"};
  EXPECT_EQ(pair.run([&] { return pair.read(Clock::now() + 5s); }), whole_reply);
}

TEST(ReadDeadline, SilenceEndsTheReadAtTheDeadlineAndALaterByteIsReadNext) {
  LoopbackPair pair;
  const auto [silent, taken] = pair.run([&] { return pair.read(Clock::now() + 20ms); });
  EXPECT_EQ(silent, std::errc::timed_out);
  EXPECT_EQ(taken, "");
  pair.send("late\r");
  const auto [ec, text] = pair.run([&] { return pair.read(Clock::now() + 5s); });
  EXPECT_FALSE(ec);
  EXPECT_EQ(text, "late\r");
}

TEST(ReadDeadline, AfterATimeoutTheBufferedBytesAreStillAvailable) {
  LoopbackPair pair;
  const auto [ec, taken] = pair.run([&] { return pair.read(Clock::now() + 10ms); });
  EXPECT_EQ(ec, std::errc::timed_out);
  pair.send("backlog\r");
  std::this_thread::sleep_for(20ms);
  char chunk[64];
  const auto got = pair.transport.read_available(asio::buffer(chunk));
  EXPECT_EQ(std::string(chunk, got), "backlog\r");
}

TEST(ReadDeadline, DataAlreadyWaitingWinsOverADeadlineAlreadyPassed) {
  LoopbackPair pair;
  pair.send("ready\r");
  std::this_thread::sleep_for(20ms);
  const auto [ec, text] = pair.run([&] { return pair.read(Clock::now() - 1s); });
  EXPECT_FALSE(ec);
  EXPECT_EQ(text, "ready\r");
}

TEST(ReadDeadline, ADeadlineOfAnEarlierReadDoesNotCancelTheNextOne) {
  LoopbackPair pair;
  pair.send("a");
  // This read completes with data long before its deadline; its timer must not end the next.
  const auto [first, a] = pair.run([&] { return pair.read(Clock::now() + 30ms); });
  EXPECT_FALSE(first);
  EXPECT_EQ(a, "a");
  asio::steady_timer later(pair.io, 60ms);
  later.async_wait([&](const boost::system::error_code&) { pair.send("b"); });
  const auto [ec, text] = pair.run([&] { return pair.read(Clock::now() + 5s); });
  EXPECT_FALSE(ec);
  EXPECT_EQ(text, "b");
}

TEST(ReadDeadline, AReadWithAnEarlierDeadlineThanTheLastEndsAtItsOwn) {
  LoopbackPair pair;
  pair.send("a");
  // A read that ends with data long before its 10 s, then one that must end at its own 20 ms.
  const auto [ec, text] =
      pair.run([&]() -> asio::awaitable<std::pair<std::error_code, std::string>> {
        const auto first = co_await pair.read(Clock::now() + 10s);
        EXPECT_EQ(first.second, "a");
        co_return co_await pair.read(Clock::now() + 20ms);
      });
  EXPECT_EQ(ec, std::errc::timed_out);
  EXPECT_EQ(text, "");
}

TEST(ReadDeadline, ATransportGoneWithItsTimerSetLeavesTheLoopRunning) {
  asio::io_context io;
  {
    LoopbackPair pair;
    pair.send("x");
    pair.run([&]() -> asio::awaitable<void> {
      char chunk[8];
      co_await pair.transport.read_some_until(asio::buffer(chunk), Clock::now() + 10ms);
    });
    // The pair (its io_context, transport and timer) goes while the timer is still set.
  }
  asio::steady_timer after(io, 30ms);
  bool ran = false;
  after.async_wait([&](const boost::system::error_code&) { ran = true; });
  io.run();
  EXPECT_TRUE(ran);
}

TEST(ReadDeadline, AClosedPeerIsAnErrorNotATimeout) {
  LoopbackPair pair;
  pair.peer.close();
  const auto [ec, text] = pair.run([&] { return pair.read(Clock::now() + 5s); });
  EXPECT_TRUE(ec);
  EXPECT_NE(ec, std::errc::timed_out);
  EXPECT_EQ(text, "");
}

// The default read_some_until, for transports that only have read_some (test fakes): a read
// waits until write() hands it bytes, or until it is cancelled.
class QuietTransport final : public ByteTransport {
 public:
  explicit QuietTransport(asio::io_context& io) : wake_(io) {}
  asio::awaitable<std::error_code> open() override { co_return std::error_code{}; }
  void close() override {}
  bool is_open() const override { return true; }
  asio::awaitable<std::error_code> write(std::string_view text) override {
    pending_ = std::string(text);
    wake_.cancel();
    co_return std::error_code{};
  }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    if (pending_.empty()) {
      wake_.expires_at(asio::steady_timer::time_point::max());
      auto [ec] = co_await wake_.async_wait(asio::as_tuple(asio::use_awaitable));
      if (pending_.empty()) co_return std::pair{std::error_code(ec), std::size_t{0}};
    }
    co_return std::pair{std::error_code{}, read_available(buffer)};
  }
  std::size_t read_available(asio::mutable_buffer buffer) override {
    const auto n = std::min(buffer.size(), pending_.size());
    std::memcpy(buffer.data(), pending_.data(), n);
    pending_.erase(0, n);
    return n;
  }
  void discard_input() override { pending_.clear(); }
  std::string describe() const override { return "quiet"; }
  double char_time_us() const override { return 0; }

 private:
  asio::steady_timer wake_;
  std::string pending_;
};

TEST(ReadDeadline, TheDefaultRaceTimesOutAndThenReadsWhatCameLater) {
  asio::io_context io;
  QuietTransport transport(io);
  auto done = asio::co_spawn(
      io,
      [&]() -> asio::awaitable<std::pair<std::error_code, std::string>> {
        char chunk[64];
        auto [e, n] = co_await transport.read_some_until(asio::buffer(chunk), Clock::now() + 10ms);
        EXPECT_EQ(n, 0u);
        co_await transport.write("echo\r");
        auto [e2, n2] = co_await transport.read_some_until(asio::buffer(chunk), Clock::now() + 5s);
        EXPECT_FALSE(e2);
        co_return std::pair{e, std::string(chunk, n2)};
      },
      asio::use_future);
  io.run();
  const auto [first, second] = done.get();
  EXPECT_EQ(first, std::errc::timed_out);
  EXPECT_EQ(second, "echo\r");
}

}  // namespace
}  // namespace fieldgate
