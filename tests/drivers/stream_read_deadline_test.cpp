// StreamTransport::read_some_until on a real PTY: its one timer for the transport's life gives a
// read up at its deadline, and only that read (an earlier read's deadline cuts no later read;
// a read cancelled by its caller is an error, not a timeout).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <boost/asio/bind_cancellation_slot.hpp>
#include <boost/asio/cancellation_signal.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include "drivers/transport/serial_transport.hpp"
#include "tests/harness/fake_line.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

class StreamReadDeadline : public ::testing::Test {
 protected:
  StreamReadDeadline() {
    char name[64];
    if (::openpty(&device_, &port_, name, nullptr, nullptr) != 0) throw std::runtime_error("pty");
    termios tio{};
    ::tcgetattr(port_, &tio);
    ::cfmakeraw(&tio);
    ::tcsetattr(port_, TCSANOW, &tio);
    transport_.emplace(io_.get_executor(), SerialSettings{name, 115200});
    EXPECT_FALSE(run(transport_->open()));
  }
  ~StreamReadDeadline() override {
    transport_.reset();
    ::close(port_);
    ::close(device_);
  }

  template <typename T>
  T run(asio::awaitable<T> op) {
    return test::run(io_, std::move(op));
  }

  asio::awaitable<TransportRead> read_until(Clock::time_point deadline) {
    auto got = co_await transport_->read_some_until(asio::buffer(chunk_), deadline);
    co_return got;
  }

  // The device side writes `bytes` after `delay`, while the io_context runs.
  void device_writes_after(std::chrono::milliseconds delay, std::string bytes) {
    auto timer = std::make_shared<asio::steady_timer>(io_, delay);
    timer->async_wait([this, timer, bytes](const boost::system::error_code&) {
      EXPECT_EQ(::write(device_, bytes.data(), bytes.size()), static_cast<ssize_t>(bytes.size()));
    });
  }

  std::string got_text(const TransportRead& r) const { return std::string(chunk_, r.size); }

  asio::io_context io_;
  int device_ = -1;
  int port_ = -1;
  std::optional<SerialTransport> transport_;
  char chunk_[64];
};

TEST_F(StreamReadDeadline, BytesBeforeTheDeadlineAreARead) {
  ASSERT_EQ(::write(device_, "AB", 2), 2);
  const auto got = run(read_until(Clock::now() + 5s));
  EXPECT_FALSE(got.timed_out);
  EXPECT_FALSE(got.error);
  EXPECT_EQ(got_text(got), "AB");
}

TEST_F(StreamReadDeadline, NothingByTheDeadlineIsATimeoutNotBeforeIt) {
  const auto deadline = Clock::now() + 30ms;
  const auto got = run(read_until(deadline));
  EXPECT_TRUE(got.timed_out);
  EXPECT_FALSE(got.error) << got.error.message();
  EXPECT_EQ(got.size, 0u);
  EXPECT_GE(Clock::now(), deadline);
}

TEST_F(StreamReadDeadline, TheLineStillReadsAfterATimeout) {
  ASSERT_TRUE(run(read_until(Clock::now() + 10ms)).timed_out);
  device_writes_after(20ms, "C");
  const auto got = run(read_until(Clock::now() + 5s));
  EXPECT_FALSE(got.timed_out);
  EXPECT_EQ(got_text(got), "C");
}

TEST_F(StreamReadDeadline, AnEarlierReadsDeadlineCutsNoLaterRead) {
  ASSERT_EQ(::write(device_, "1", 1), 1);
  const auto first = run(read_until(Clock::now() + 40ms));
  ASSERT_EQ(got_text(first), "1");
  // The first read's 40 ms pass while the second waits for a byte that comes at 150 ms.
  device_writes_after(150ms, "2");
  const auto second = run(read_until(Clock::now() + 5s));
  EXPECT_FALSE(second.timed_out);
  EXPECT_FALSE(second.error) << second.error.message();
  EXPECT_EQ(got_text(second), "2");
}

// The reply and the deadline seen in one turn of the loop (a stalled process): the read takes the
// bytes, and its timer's handler, already on its way, must not cut the read that follows.
TEST_F(StreamReadDeadline, ADeadlineThatFiredWithTheBytesCutsNoLaterRead) {
  std::optional<TransportRead> first, second;
  asio::co_spawn(
      io_,
      [&]() -> asio::awaitable<void> {
        first = co_await transport_->read_some_until(asio::buffer(chunk_), Clock::now() + 20ms);
        second = co_await transport_->read_some_until(asio::buffer(chunk_), Clock::now() + 5s);
      },
      asio::detached);
  // Runs once the first read waits: its 20 ms pass while the byte sits in the OS.
  asio::post(io_, [&] {
    ASSERT_EQ(::write(device_, "1", 1), 1);
    std::this_thread::sleep_for(40ms);
  });
  device_writes_after(150ms, "2");
  io_.restart();
  io_.run();
  ASSERT_TRUE(first && second);
  EXPECT_FALSE(first->timed_out);
  EXPECT_EQ(first->size, 1u);
  EXPECT_FALSE(second->timed_out) << "the first read's deadline cut the second";
  EXPECT_FALSE(second->error) << second->error.message();
  EXPECT_EQ(second->size, 1u);
}

TEST_F(StreamReadDeadline, ACallersCancellationIsAnErrorNotATimeout) {
  asio::cancellation_signal cancel;
  std::optional<TransportRead> got;
  asio::co_spawn(io_, read_until(Clock::now() + 5s),
                 asio::bind_cancellation_slot(
                     cancel.slot(), [&](std::exception_ptr, TransportRead r) { got = r; }));
  asio::steady_timer later(io_, 20ms);
  later.async_wait(
      [&](const boost::system::error_code&) { cancel.emit(asio::cancellation_type::terminal); });
  io_.restart();
  io_.run();
  ASSERT_TRUE(got);
  EXPECT_FALSE(got->timed_out);
  EXPECT_TRUE(got->error);
  // The transport's timer belongs to no read now: the next one still waits for its byte.
  device_writes_after(60ms, "3");
  const auto next = run(read_until(Clock::now() + 5s));
  EXPECT_FALSE(next.timed_out);
  EXPECT_EQ(got_text(next), "3");
}

}  // namespace
}  // namespace fieldgate
