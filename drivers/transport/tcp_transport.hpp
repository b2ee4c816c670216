#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/ip/tcp.hpp>

#include "drivers/transport/stream_transport.hpp"

namespace fieldgate {

// A serial device server (terminal server) port reached over TCP in raw mode.
class TcpTransport final : public StreamTransport<asio::ip::tcp::socket> {
 public:
  TcpTransport(asio::any_io_executor executor, std::string host, uint16_t port,
               double char_time_us);

  asio::awaitable<std::error_code> open() override;
  std::size_t read_available(asio::mutable_buffer buffer) override;
  std::size_t write_available(std::string_view bytes) override;
  void discard_input() override;
  std::string describe() const override;
  double char_time_us() const override { return char_time_us_; }

 private:
  std::string host_;
  uint16_t port_;
  double char_time_us_;
};

}  // namespace fieldgate
