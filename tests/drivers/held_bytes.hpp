#pragma once

// The OS input queue of a serial port, in memory, for Link's tests: bytes it holds (`held`) are
// handed out by read_available and by reads; an asynchronous read waits for bytes put in
// `later`, and is counted; a device that never stops (`chatter`) refills the queue on every
// read; flushes are counted.

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/use_future.hpp>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <string>
#include <utility>

#include "drivers/link.hpp"

namespace fieldgate::test {

class HeldBytes final : public ByteTransport {
 public:
  std::string held;
  std::string later;
  bool chatter = false;
  int reads_started = 0;
  int flushes = 0;

  asio::awaitable<std::error_code> open() override { co_return std::error_code{}; }
  void close() override {}
  bool is_open() const override { return true; }
  std::string written;
  std::size_t takes_at_once = static_cast<std::size_t>(-1);  // write_available's room

  asio::awaitable<std::error_code> write(std::string_view bytes) override {
    written += bytes;
    co_return std::error_code{};
  }
  std::size_t write_available(std::string_view bytes) override {
    const std::size_t n = std::min(bytes.size(), takes_at_once);
    written += bytes.substr(0, n);
    return n;
  }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    ++reads_started;
    asio::steady_timer tick(co_await asio::this_coro::executor);
    while (held.empty() && !chatter) {
      held = std::exchange(later, {});
      tick.expires_after(std::chrono::milliseconds(1));
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
  std::string describe() const override { return "held bytes"; }
  double char_time_us() const override { return 0; }
};

// read_frame keeps a reference to its splitter: it must outlive the read.
inline const FrameSplitter kLine = [](std::string_view b) -> std::size_t {
  const auto p = b.find('\r');
  return p == std::string_view::npos ? 0 : p + 1;
};

inline const LinkTiming kNoWait{std::chrono::microseconds(0), std::chrono::microseconds(0)};

// One read_frame on its own event loop.
inline LinkRead read_now(Link& link, const LinkTiming& timing) {
  asio::io_context io;
  auto read = asio::co_spawn(io, link.read_frame(kLine, timing), asio::use_future);
  io.run();
  return read.get();
}

}  // namespace fieldgate::test
