#include "drivers/transport/byte_transport.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/experimental/awaitable_operators.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

namespace fieldgate {

using namespace boost::asio::experimental::awaitable_operators;

asio::awaitable<TransportRead> ByteTransport::read_some_until(
    asio::mutable_buffer buffer, std::chrono::steady_clock::time_point deadline) {
  asio::steady_timer timer(co_await asio::this_coro::executor, deadline);
  auto outcome =
      co_await (read_some(buffer) || timer.async_wait(asio::as_tuple(asio::use_awaitable)));
  if (outcome.index() == 1) co_return TransportRead{{}, 0, true};
  const auto [ec, n] = std::get<0>(outcome);
  co_return TransportRead{ec, n, false};
}

}  // namespace fieldgate
