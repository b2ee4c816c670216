#pragma once

// The accept loop of the daemon's small HTTP servers (metrics, console). Their State has an
// `acceptor`, an `accept_retry` timer, `open` (connections being served), `connections` (an
// HttpConnections), `stopped`, and `stats.accepted` / `stats.refused` / `stats.evicted`; it is
// shared with the connection coroutines. A State with `denies(peer)` (and `stats.denied`) has
// the peers it denies closed at once, before they take a slot.

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/ip/address.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/beast/core/tcp_stream.hpp>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <list>
#include <memory>

namespace fieldgate {

namespace asio = boost::asio;

// One connection being served, as the accept loop sees it.
struct HttpConnection {
  asio::ip::address peer;  // IPv4-mapped addresses as IPv4
  std::chrono::steady_clock::time_point accepted = std::chrono::steady_clock::now();
  // Its request was read and let in (address and token). Until then it may be a slow or
  // stalled client holding a slot, and it is the first to go when a newcomer needs room.
  bool admitted = false;
  bool closing = false;  // evicted; its coroutine has not finished yet
  boost::beast::tcp_stream* stream = nullptr;
};

struct HttpConnectionLimits {
  std::size_t max_open = 0;  // connections at once
  // Connections from one peer address not yet admitted; beyond it, a newcomer from there takes
  // the slot of that address's oldest such connection. 0: no limit.
  std::size_t max_pending_per_address = 0;
};

using HttpConnections = std::list<std::shared_ptr<HttpConnection>>;

namespace http_accept_detail {

inline asio::ip::address plain(const asio::ip::address& a) {
  if (a.is_v6() && a.to_v6().is_v4_mapped())
    return asio::ip::make_address_v4(asio::ip::v4_mapped, a.to_v6());
  return a;
}

// Makes room for a newcomer from `peer`: false if there is none to make. Only a connection not
// yet admitted is closed for it (the one waiting longest for its request), so an admitted
// request never waits behind slots held by clients that send nothing, however fast they
// reconnect.
inline bool make_room(HttpConnections& connections, const asio::ip::address& peer,
                      const HttpConnectionLimits& limits, std::uint64_t& evicted) {
  std::size_t open = 0, pending_from_peer = 0;
  for (const auto& c : connections) {
    if (c->closing) continue;
    ++open;
    if (c->peer == peer && !c->admitted) ++pending_from_peer;
  }
  const bool peer_full =
      limits.max_pending_per_address != 0 && pending_from_peer >= limits.max_pending_per_address;
  if (open < limits.max_open && !peer_full) return true;
  std::shared_ptr<HttpConnection> victim;
  for (const auto& c : connections) {
    if (c->closing || c->admitted || (peer_full && c->peer != peer)) continue;
    if (!victim || c->accepted < victim->accepted) victim = c;
  }
  if (!victim) return false;
  victim->closing = true;
  if (victim->stream) victim->stream->close();
  ++evicted;
  return true;
}

}  // namespace http_accept_detail

// Serves each accepted connection with exchange(stream, state, connection) in a coroutine of
// its own. Beyond the limits a connection is closed at once (after make_room found nothing to
// evict), so clients that stall cannot use up the descriptors the Modbus server needs; an
// accept error (EMFILE) is retried after a pause.
template <typename State, typename Exchange>
asio::awaitable<void> accept_http_connections(std::shared_ptr<State> state,
                                              HttpConnectionLimits limits, Exchange exchange) {
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
    boost::system::error_code peer_ec;
    const auto peer = http_accept_detail::plain(socket.remote_endpoint(peer_ec).address());
    if (peer_ec) continue;  // already gone
    if constexpr (requires { state->denies(peer); }) {
      if (state->denies(peer)) {
        ++state->stats.denied;  // closed unanswered as the socket goes out of scope
        continue;
      }
    }
    if (!http_accept_detail::make_room(state->connections, peer, limits, state->stats.evicted)) {
      ++state->stats.refused;
      continue;
    }
    ++state->stats.accepted;
    ++state->open;
    auto connection = std::make_shared<HttpConnection>();
    connection->peer = peer;
    state->connections.push_back(connection);
    asio::co_spawn(
        state->acceptor.get_executor(),
        [](boost::beast::tcp_stream stream, std::shared_ptr<State> s, HttpConnections::iterator at,
           Exchange serve) -> asio::awaitable<void> {
          HttpConnection& c = **at;
          c.stream = &stream;
          // Evicted between the accept and this start: nothing to serve.
          if (!c.closing) {
            try {
              co_await serve(stream, *s, c);
            } catch (...) {
              // Belongs to this connection alone.
            }
          }
          c.stream = nullptr;
          s->connections.erase(at);
          --s->open;
        }(boost::beast::tcp_stream(std::move(socket)), state, std::prev(state->connections.end()),
                           exchange),
        asio::detached);
  }
}

// Starts accept_http_connections on the acceptor's executor.
template <typename State, typename Exchange>
void start_accepting(std::shared_ptr<State> state, HttpConnectionLimits limits, Exchange exchange) {
  auto executor = state->acceptor.get_executor();
  asio::co_spawn(executor, accept_http_connections(std::move(state), limits, exchange),
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
