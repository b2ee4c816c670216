#include "drivers/transport/tcp_transport.hpp"

#include <fmt/format.h>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/connect.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/write.hpp>

namespace fieldgate {

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
std::error_code to_std(const boost::system::error_code& ec) {
  return ec ? std::error_code(ec.value(), std::generic_category()) : std::error_code{};
}
}  // namespace

TcpTransport::TcpTransport(asio::any_io_executor executor, std::string host, uint16_t port,
                           double char_time_us)
    : host_(std::move(host)), port_(port), char_time_us_(char_time_us), socket_(executor) {}

asio::awaitable<std::error_code> TcpTransport::open() {
  asio::ip::tcp::resolver resolver(socket_.get_executor());
  auto [rec, endpoints] = co_await resolver.async_resolve(host_, std::to_string(port_), use_tuple);
  if (rec) co_return to_std(rec);
  auto [cec, ep] = co_await asio::async_connect(socket_, endpoints, use_tuple);
  (void)ep;
  if (cec) {
    close();
    co_return to_std(cec);
  }
  socket_.set_option(asio::ip::tcp::no_delay(true));
  co_return std::error_code{};
}

void TcpTransport::close() {
  boost::system::error_code ignored;
  socket_.close(ignored);
}

asio::awaitable<std::error_code> TcpTransport::write(std::string_view bytes) {
  auto [ec, n] =
      co_await asio::async_write(socket_, asio::buffer(bytes.data(), bytes.size()), use_tuple);
  (void)n;
  co_return to_std(ec);
}

asio::awaitable<std::pair<std::error_code, std::size_t>> TcpTransport::read_some(
    asio::mutable_buffer buffer) {
  auto [ec, n] = co_await socket_.async_read_some(buffer, use_tuple);
  co_return std::pair{to_std(ec), n};
}

std::size_t TcpTransport::read_available(asio::mutable_buffer buffer) {
  boost::system::error_code ec;
  if (!socket_.is_open() || socket_.available(ec) == 0 || ec) return 0;
  const auto n = socket_.read_some(buffer, ec);
  return ec ? 0 : n;
}

void TcpTransport::discard_input() {
  if (!socket_.is_open()) return;
  char scratch[512];
  boost::system::error_code ec;
  while (socket_.available(ec) > 0 && !ec) socket_.read_some(asio::buffer(scratch), ec);
}

std::string TcpTransport::describe() const {
  return fmt::format("tcp://{}:{}", host_, port_);
}

}  // namespace fieldgate
