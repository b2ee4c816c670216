#include "drivers/transport/serial_transport.hpp"

#include <fmt/format.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>

namespace fieldgate {

double serial_char_time_us(const SerialSettings& s) {
  const unsigned bits = 1 + s.data_bits + (s.parity == 'N' ? 0 : 1) + s.stop_bits;
  return s.baud == 0 ? 0.0 : 1e6 * bits / s.baud;
}

SerialTransport::SerialTransport(asio::any_io_executor executor, SerialSettings settings)
    : StreamTransport(executor), settings_(std::move(settings)), current_baud_(settings_.baud) {}

std::error_code SerialTransport::set_baud(unsigned baud) {
  boost::system::error_code ec;
  stream_.set_option(asio::serial_port_base::baud_rate(baud), ec);
  if (ec) return to_std_error(ec);
  current_baud_ = baud;
  return {};
}

asio::awaitable<std::error_code> SerialTransport::write(std::string_view bytes) {
  // A request fits the OS's output queue: written here (asio opens the port O_NONBLOCK), the
  // exchange goes on to its reply without a turn of the event loop in between.
  if (stream_.is_open()) {
    const auto n = ::write(stream_.native_handle(), bytes.data(), bytes.size());
    if (n == static_cast<ssize_t>(bytes.size())) co_return std::error_code{};
    if (n > 0)
      bytes.remove_prefix(static_cast<std::size_t>(n));
    else if (n < 0 && errno != EAGAIN && errno != EINTR)
      co_return std::error_code(errno, std::generic_category());
  }
  co_return co_await StreamTransport::write(bytes);
}

void SerialTransport::drain() {
  if (stream_.is_open()) ::tcdrain(stream_.native_handle());
}

asio::awaitable<std::error_code> SerialTransport::open() {
  boost::system::error_code ec;
  stream_.open(settings_.device, ec);
  if (ec) co_return to_std_error(ec);
  using sp = asio::serial_port_base;
  const sp::parity::type parity = settings_.parity == 'E'   ? sp::parity::even
                                  : settings_.parity == 'O' ? sp::parity::odd
                                                            : sp::parity::none;
  current_baud_ = settings_.baud;
  stream_.set_option(sp::baud_rate(settings_.baud), ec);
  if (!ec) stream_.set_option(sp::character_size(settings_.data_bits), ec);
  if (!ec) stream_.set_option(sp::parity(parity), ec);
  if (!ec)
    stream_.set_option(
        sp::stop_bits(settings_.stop_bits == 2 ? sp::stop_bits::two : sp::stop_bits::one), ec);
  if (!ec) stream_.set_option(sp::flow_control(sp::flow_control::none), ec);
  if (ec) {
    stream_.close();
    co_return to_std_error(ec);
  }
  ::tcflush(stream_.native_handle(), TCIOFLUSH);
  co_return std::error_code{};
}

std::size_t SerialTransport::read_available(asio::mutable_buffer buffer) {
  if (!stream_.is_open()) return 0;
  // The port is O_NONBLOCK, so an empty queue is EAGAIN. Asking FIONREAD first would take the
  // line discipline's termios lock for writing, which waits out the receive work in progress.
  const auto n = ::read(stream_.native_handle(), buffer.data(), buffer.size());
  return n > 0 ? static_cast<std::size_t>(n) : 0;
}

std::size_t SerialTransport::write_available(std::string_view bytes) {
  if (!stream_.is_open()) return 0;
  // O_NONBLOCK, as in read_available: a full output queue is EAGAIN, and a failed port fails
  // the exchange's own send.
  const auto n = ::write(stream_.native_handle(), bytes.data(), bytes.size());
  return n > 0 ? static_cast<std::size_t>(n) : 0;
}

void SerialTransport::discard_input() {
  if (stream_.is_open()) ::tcflush(stream_.native_handle(), TCIFLUSH);
}

std::string SerialTransport::describe() const {
  return fmt::format("{} {} {}{}{}", settings_.device, settings_.baud, settings_.data_bits,
                     settings_.parity, settings_.stop_bits);
}

}  // namespace fieldgate
