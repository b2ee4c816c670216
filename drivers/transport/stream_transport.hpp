#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/as_tuple.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/write.hpp>
#include <boost/system/error_code.hpp>

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

 protected:
  explicit StreamTransport(asio::any_io_executor executor) : stream_(executor) {}

  Stream stream_;
};

}  // namespace fieldgate
