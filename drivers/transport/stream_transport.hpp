#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/as_tuple.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/write.hpp>
#include <boost/system/error_code.hpp>

#include <chrono>
#include <cstdint>

#include "drivers/transport/byte_transport.hpp"

namespace fieldgate {

inline std::error_code to_std_error(const boost::system::error_code& ec) {
  return ec ? std::error_code(ec.value(), std::generic_category()) : std::error_code{};
}

// A transport over an asio stream (a serial port, a TCP socket): closing, writing and reading
// are the stream's own; opening and the rest are the transport's.
template <typename Stream>
class StreamTransport : public ByteTransport {
 public:
  void close() override {
    boost::system::error_code ignored;
    stream_.close(ignored);
  }
  bool is_open() const override { return stream_.is_open(); }
  asio::awaitable<std::error_code> write(std::string_view bytes) override {
    auto [ec, n] = co_await asio::async_write(stream_, asio::buffer(bytes.data(), bytes.size()),
                                              asio::as_tuple(asio::use_awaitable));
    (void)n;
    co_return to_std_error(ec);
  }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    auto [ec, n] = co_await stream_.async_read_some(buffer, asio::as_tuple(asio::use_awaitable));
    co_return std::pair{to_std_error(ec), n};
  }
  // The deadline cancels the stream's read from a plain timer callback. A callback that comes
  // after its read completed (both ready at once, or already queued when the read's completion
  // cancelled the timer) finds the read generation moved on and does nothing; one that comes
  // after the transport is gone sees operation_aborted and touches nothing.
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some_until(
      asio::mutable_buffer buffer, std::chrono::steady_clock::time_point deadline) override {
    const std::uint64_t generation = ++read_generation_;
    deadline_.expires_at(deadline);
    deadline_.async_wait([this, generation](const boost::system::error_code& ec) {
      if (ec || generation != read_generation_) return;
      timed_out_read_ = generation;
      boost::system::error_code ignored;
      stream_.cancel(ignored);
    });
    auto [ec, n] = co_await stream_.async_read_some(buffer, asio::as_tuple(asio::use_awaitable));
    ++read_generation_;
    deadline_.cancel();
    if (n > 0) co_return std::pair{std::error_code{}, n};
    if (timed_out_read_ == generation)
      co_return std::pair{std::make_error_code(std::errc::timed_out), std::size_t{0}};
    co_return std::pair{to_std_error(ec), n};
  }

 protected:
  explicit StreamTransport(asio::any_io_executor executor)
      : stream_(executor), deadline_(executor) {}

  Stream stream_;

 private:
  asio::steady_timer deadline_;
  std::uint64_t read_generation_ = 0;
  std::uint64_t timed_out_read_ = 0;
};

}  // namespace fieldgate
