#include "drivers/transport/byte_transport.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/experimental/awaitable_operators.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

namespace fieldgate {

using namespace boost::asio::experimental::awaitable_operators;

asio::awaitable<std::pair<std::error_code, std::size_t>> ByteTransport::read_some_until(
    asio::mutable_buffer buffer, std::chrono::steady_clock::time_point deadline) {
  asio::steady_timer timer(co_await asio::this_coro::executor, deadline);
  auto outcome =
      co_await (read_some(buffer) || timer.async_wait(asio::as_tuple(asio::use_awaitable)));
  if (outcome.index() == 1)
    co_return std::pair{std::make_error_code(std::errc::timed_out), std::size_t{0}};
  co_return std::get<0>(outcome);
}

}  // namespace fieldgate
