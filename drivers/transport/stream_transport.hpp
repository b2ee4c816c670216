#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/as_tuple.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/write.hpp>
#include <boost/system/error_code.hpp>

#include <cstdint>
#include <memory>

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
  // One timer for the transport's life, which cancels the stream's read when it expires: no
  // coroutines or parallel group per read.
  asio::awaitable<TransportRead> read_some_until(
      asio::mutable_buffer buffer, std::chrono::steady_clock::time_point deadline) override {
    const auto read = ++deadline_->read;
    deadline_->expired = false;
    deadline_->timer.expires_at(deadline);
    deadline_->timer.async_wait([d = deadline_, read](const boost::system::error_code& ec) {
      // A timer that was re-armed, cancelled or outlived its read (or its transport) is not
      // this read's deadline.
      if (ec || read != d->read) return;
      d->expired = true;
      boost::system::error_code ignored;
      if (d->stream) d->stream->cancel(ignored);
    });
    auto [ec, n] = co_await stream_.async_read_some(buffer, asio::as_tuple(asio::use_awaitable));
    ++deadline_->read;
    if (deadline_->expired) {
      if (ec == asio::error::operation_aborted) co_return TransportRead{{}, 0, true};
    } else {
      deadline_->timer.cancel();
    }
    co_return TransportRead{to_std_error(ec), n, false};
  }

 protected:
  explicit StreamTransport(asio::any_io_executor executor)
      : stream_(executor), deadline_(std::make_shared<Deadline>(executor, stream_)) {}
  ~StreamTransport() override {
    ++deadline_->read;
    deadline_->stream = nullptr;
    deadline_->timer.cancel();
  }

  Stream stream_;

 private:
  // Shared with the timer's handler, which can run after the transport has gone.
  struct Deadline {
    Deadline(asio::any_io_executor executor, Stream& s) : timer(executor), stream(&s) {}
    asio::steady_timer timer;
    std::uint64_t read = 0;  // which read the armed timer belongs to
    bool expired = false;
    Stream* stream;
  };
  std::shared_ptr<Deadline> deadline_;
};

}  // namespace fieldgate
