#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/serial_port.hpp>

#include "drivers/transport/stream_transport.hpp"

namespace fieldgate {

struct SerialSettings {
  std::string device;
  unsigned baud = 9600;
  unsigned data_bits = 8;
  char parity = 'N';  // N, E, O
  unsigned stop_bits = 1;
};

double serial_char_time_us(const SerialSettings& settings);

class SerialTransport final : public StreamTransport<asio::serial_port> {
 public:
  SerialTransport(asio::any_io_executor executor, SerialSettings settings);

  asio::awaitable<std::error_code> open() override;
  asio::awaitable<std::error_code> write(std::string_view bytes) override;
  std::size_t read_available(asio::mutable_buffer buffer) override;
  std::size_t write_available(std::string_view bytes) override;
  std::error_code set_baud(unsigned baud) override;
  unsigned baud() const override { return current_baud_; }
  void drain() override;
  void discard_input() override;
  std::string describe() const override;
  double char_time_us() const override { return serial_char_time_us(settings_); }

 private:
  SerialSettings settings_;
  unsigned current_baud_;
};

}  // namespace fieldgate
