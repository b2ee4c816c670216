#include "drivers/transport/tcp_transport.hpp"

#include <fmt/format.h>
#include <sys/socket.h>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/connect.hpp>
#include <boost/asio/use_awaitable.hpp>

namespace fieldgate {

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
}

TcpTransport::TcpTransport(asio::any_io_executor executor, std::string host, uint16_t port,
                           double char_time_us)
    : StreamTransport(executor), host_(std::move(host)), port_(port), char_time_us_(char_time_us) {}

asio::awaitable<std::error_code> TcpTransport::open() {
  asio::ip::tcp::resolver resolver(stream_.get_executor());
  auto [rec, endpoints] = co_await resolver.async_resolve(host_, std::to_string(port_), use_tuple);
  if (rec) co_return to_std_error(rec);
  auto [cec, ep] = co_await asio::async_connect(stream_, endpoints, use_tuple);
  (void)ep;
  if (cec) {
    close();
    co_return to_std_error(cec);
  }
  stream_.set_option(asio::ip::tcp::no_delay(true));
  co_return std::error_code{};
}

std::size_t TcpTransport::read_available(asio::mutable_buffer buffer) {
  boost::system::error_code ec;
  if (!stream_.is_open() || stream_.available(ec) == 0 || ec) return 0;
  const auto n = stream_.read_some(buffer, ec);
  return ec ? 0 : n;
}

std::size_t TcpTransport::write_available(std::string_view bytes) {
  if (!stream_.is_open()) return 0;
  // Whatever asio's own mode of the socket: this send never waits, and a closed peer is no signal.
  const auto n =
      ::send(stream_.native_handle(), bytes.data(), bytes.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
  return n > 0 ? static_cast<std::size_t>(n) : 0;
}

void TcpTransport::discard_input() {
  if (!stream_.is_open()) return;
  char scratch[512];
  boost::system::error_code ec;
  while (stream_.available(ec) > 0 && !ec) stream_.read_some(asio::buffer(scratch), ec);
}

std::string TcpTransport::describe() const {
  return fmt::format("tcp://{}:{}", host_, port_);
}

}  // namespace fieldgate
