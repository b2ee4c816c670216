#pragma once

// The accept loop of the daemon's small HTTP servers (metrics, console). Their State has an
// `acceptor`, an `accept_retry` timer, `open` (connections being served), `stopped`, and
// `stats.accepted` / `stats.refused`; it is shared with the connection coroutines.

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/beast/core/tcp_stream.hpp>

#include <chrono>
#include <cstddef>
#include <memory>

namespace fieldgate {

namespace asio = boost::asio;

// Serves each accepted connection with exchange(stream, state) in a coroutine of its own.
// Beyond `max_open` a connection is closed at once, so clients that stall cannot use up the
// descriptors the Modbus server needs; an accept error (EMFILE) is retried after a pause.
template <typename State, typename Exchange>
asio::awaitable<void> accept_http_connections(std::shared_ptr<State> state, std::size_t max_open,
                                              Exchange exchange) {
  constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
  while (!state->stopped) {
    auto [ec, socket] = co_await state->acceptor.async_accept(use_tuple);
    if (state->stopped) co_return;
    if (ec) {
      // Retrying at once would spin; stop() closes the acceptor meanwhile.
      state->accept_retry.expires_after(std::chrono::milliseconds(100));
      co_await state->accept_retry.async_wait(use_tuple);
      continue;
    }
    if (state->open >= max_open) {
      ++state->stats.refused;
      continue;
    }
    ++state->stats.accepted;
    ++state->open;
    asio::co_spawn(
        state->acceptor.get_executor(),
        [](boost::beast::tcp_stream stream, std::shared_ptr<State> s,
           Exchange serve) -> asio::awaitable<void> {
          try {
            co_await serve(stream, *s);
          } catch (...) {
            // Belongs to this connection alone.
          }
          --s->open;
        }(boost::beast::tcp_stream(std::move(socket)), state, exchange),
        asio::detached);
  }
}

// Starts accept_http_connections on the acceptor's executor.
template <typename State, typename Exchange>
void start_accepting(std::shared_ptr<State> state, std::size_t max_open, Exchange exchange) {
  auto executor = state->acceptor.get_executor();
  asio::co_spawn(executor, accept_http_connections(std::move(state), max_open, exchange),
                 asio::detached);
}

// Ends the accept loop: connections being served finish on their own deadlines.
template <typename State>
void stop_accepting(State& state) {
  state.stopped = true;
  boost::system::error_code ignored;
  state.acceptor.close(ignored);
  state.accept_retry.cancel();
}

}  // namespace fieldgate
