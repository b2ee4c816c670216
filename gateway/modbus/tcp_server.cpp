#include "gateway/modbus/tcp_server.hpp"

#include <list>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/experimental/awaitable_operators.hpp>
#include <boost/asio/ip/v6_only.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/write.hpp>

#include "gateway/modbus/mbap.hpp"

namespace fieldgate::modbus {

using asio::ip::tcp;
using Clock = std::chrono::steady_clock;
using namespace asio::experimental::awaitable_operators;

namespace {

constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);

asio::ip::address plain_address(const asio::ip::address& address) {
  if (address.is_v6() && address.to_v6().is_v4_mapped()) {
    return asio::ip::make_address_v4(asio::ip::v4_mapped, address.to_v6());
  }
  return address;
}

Clock::time_point after(Clock::duration timeout) {
  return timeout == Clock::duration::zero() ? Clock::time_point::max() : Clock::now() + timeout;
}

struct Session {
  Session(tcp::socket s, asio::ip::address peer_address, std::uint16_t peer_port_number)
      : socket(std::move(s)),
        peer(peer_address),
        peer_port(peer_port_number),
        timer(socket.get_executor()) {}

  // The watchdog sleeps until the deadline; moving it earlier has to wake it.
  void set_deadline(Clock::time_point t) {
    const bool earlier = t < deadline;
    deadline = t;
    if (earlier) timer.cancel();
  }

  void close() {
    boost::system::error_code ignored;
    socket.shutdown(tcp::socket::shutdown_both, ignored);
    socket.close(ignored);
  }

  tcp::socket socket;
  asio::ip::address peer;
  std::uint16_t peer_port = 0;
  Clock::time_point connected_at = Clock::now();
  std::uint64_t requests = 0;
  std::uint64_t exceptions = 0;
  asio::steady_timer timer;
  Clock::time_point deadline = Clock::time_point::max();
  // When the last complete request arrived (or the connection, before the first one).
  Clock::time_point last_request = Clock::now();
  bool answering = false;  // a request is being answered: never evicted
  bool closing = false;    // evicted or denied; its coroutine has not finished yet
  bool timed_out = false;
  MbapFramer framer;
  std::vector<std::uint8_t> out;
};

}  // namespace

class ModbusTcpServer::Impl : public std::enable_shared_from_this<Impl> {
 public:
  Impl(asio::any_io_executor executor, ModbusTcpServerOptions options,
       std::shared_ptr<RequestHandler> handler)
      : executor_(std::move(executor)),
        options_(std::move(options)),
        handler_(std::move(handler)),
        acceptor_(executor_),
        accept_retry_(executor_) {
    const tcp::endpoint& endpoint = options_.endpoint;
    acceptor_.open(endpoint.protocol());
    acceptor_.set_option(tcp::acceptor::reuse_address(true));
    if (endpoint.address().is_v6() && endpoint.address().is_unspecified()) {
      acceptor_.set_option(asio::ip::v6_only(false));
    }
    acceptor_.bind(endpoint);
    acceptor_.listen();
  }

  void start() {
    if (started_ || stopped_) return;
    started_ = true;
    asio::co_spawn(executor_, accept_loop(shared_from_this()), asio::detached);
  }

  void stop() {
    if (stopped_) return;
    stopped_ = true;
    boost::system::error_code ignored;
    acceptor_.close(ignored);
    accept_retry_.cancel();
    for (auto& session : sessions_) session->close();
  }

  void set_handler(std::shared_ptr<RequestHandler> handler) { handler_ = std::move(handler); }

  bool reconfigure(ModbusTcpServerOptions options) {
    if (options.endpoint != options_.endpoint) return false;
    options_ = std::move(options);
    if (options_.allow_client) {
      for (auto& session : sessions_) {
        if (!options_.allow_client(session->peer)) {
          session->closing = true;
          session->close();
        }
      }
    }
    return true;
  }

  tcp::endpoint local_endpoint() const {
    boost::system::error_code ignored;
    return acceptor_.local_endpoint(ignored);
  }
  const ModbusTcpServerStats& stats() const { return stats_; }
  std::vector<ModbusClientInfo> clients() const {
    std::vector<ModbusClientInfo> out;
    const auto now = Clock::now();
    for (const auto& session : sessions_) {
      if (session->closing) continue;
      out.push_back({session->peer.to_string(), session->peer_port, now - session->connected_at,
                     now - session->last_request, session->requests, session->exceptions});
    }
    return out;
  }

 private:
  asio::awaitable<void> accept_loop(std::shared_ptr<Impl> self) {
    while (!stopped_) {
      auto [ec, socket] = co_await acceptor_.async_accept(use_tuple);
      if (stopped_) co_return;
      if (ec) {
        // E.g. EMFILE: retrying at once would spin, so pause; stop() cuts the pause short.
        accept_retry_.expires_after(std::chrono::milliseconds(100));
        co_await accept_retry_.async_wait(use_tuple);
        continue;
      }
      boost::system::error_code peer_ec;
      const auto peer = plain_address(socket.remote_endpoint(peer_ec).address());
      if (peer_ec) continue;  // already gone
      if (options_.allow_client && !options_.allow_client(peer)) {
        ++stats_.clients_denied;
        continue;  // the socket closes as it goes out of scope
      }
      if (!admit(peer)) {
        ++stats_.clients_refused;
        continue;
      }
      boost::system::error_code ignored;
      socket.set_option(tcp::no_delay(true), ignored);
      socket.set_option(tcp::socket::keep_alive(true), ignored);
      // Replies are first written directly and only awaited when the send buffer is full.
      socket.non_blocking(true, ignored);
      // The session is listed at once, so the next accept already counts it.
      const auto port = socket.remote_endpoint(peer_ec).port();
      sessions_.push_back(std::make_shared<Session>(std::move(socket), peer, port));
      ++stats_.clients_accepted;
      ++stats_.clients_connected;
      asio::co_spawn(executor_, run_session(self, std::prev(sessions_.end())), asio::detached);
    }
  }

  // Whether a new connection from `peer` may be served, making room first if the policy says so.
  bool admit(const asio::ip::address& peer) {
    std::size_t open = 0;
    std::size_t from_peer = 0;
    std::shared_ptr<Session> idlest;
    for (const auto& session : sessions_) {
      if (session->closing) continue;
      ++open;
      if (session->peer == peer) ++from_peer;
      if (!session->answering && (!idlest || session->last_request < idlest->last_request))
        idlest = session;
    }
    if (options_.max_clients_per_address != 0 && from_peer >= options_.max_clients_per_address)
      return false;
    if (options_.max_clients == 0 || open < options_.max_clients) return true;
    if (options_.when_full == WhenFull::refuse || !idlest) return false;
    idlest->closing = true;
    idlest->close();
    ++stats_.clients_evicted;
    return true;
  }

  // `self` keeps the server state alive while the client is served.
  asio::awaitable<void> run_session([[maybe_unused]] std::shared_ptr<Impl> self,
                                    std::list<std::shared_ptr<Session>>::iterator position) {
    const std::shared_ptr<Session> session = *position;
    // stop() or an eviction came between the accept and this coroutine's start: the socket is
    // closed already and the reads below fail at once.
    try {
      co_await (serve(*session) || watchdog(*session));
    } catch (...) {
      // Whatever went wrong belongs to this connection alone; it is closed below.
    }
    if (session->timed_out) ++stats_.clients_timed_out;
    session->close();
    sessions_.erase(position);
    --stats_.clients_connected;
  }

  asio::awaitable<void> serve(Session& s) {
    MbapFramer& framer = s.framer;
    Clock::time_point last_read = Clock::now();
    Clock::time_point pending_since = last_read;
    for (;;) {
      MbapFramer::Frame frame;
      MbapFramer::Status status;
      while ((status = framer.next(frame)) == MbapFramer::Status::frame) {
        s.last_request = Clock::now();
        s.answering = true;
        const bool keep_open = co_await answer(s, frame);
        s.answering = false;
        if (!keep_open) co_return;
        pending_since = last_read;
      }
      if (status != MbapFramer::Status::need_more) {
        ++stats_.framing_errors;
        co_return;
      }
      if (!framer.empty() && options_.request_timeout != Clock::duration::zero()) {
        s.set_deadline(pending_since + options_.request_timeout);
      } else {
        s.set_deadline(after(options_.idle_timeout));
      }
      const std::span<std::uint8_t> space = framer.free_space();
      auto [ec, n] =
          co_await s.socket.async_read_some(asio::buffer(space.data(), space.size()), use_tuple);
      if (ec) co_return;  // closed by the peer, by stop(), or by the watchdog
      last_read = Clock::now();
      if (framer.empty()) pending_since = last_read;
      framer.commit(n);
    }
  }

  // Handles one request and sends its reply; false if the connection is to be closed.
  asio::awaitable<bool> answer(Session& s, const MbapFramer::Frame& frame) {
    const std::uint8_t function = frame.pdu[0];
    // A reload may swap the handler meanwhile; this request finishes with the one it started.
    const std::shared_ptr<RequestHandler> handler = handler_;
    std::vector<std::uint8_t> response;
    if (handler) {
      // Reads (0x01-0x04) answer without suspending. Anything else may be a confirmed write,
      // which takes as long as the bus needs; moving the deadline back later wakes the
      // watchdog, so only do it then.
      if (function > 0x04) s.set_deadline(Clock::time_point::max());
      response = co_await dispatch(*handler, frame.header.unit_id, frame.pdu);
    } else {
      response = encode_exception(function, ExceptionCode::gateway_path_unavailable);
    }
    FunctionCounters& counters = stats_.functions[function];
    ++counters.requests;
    ++s.requests;
    if (response[0] & 0x80) {
      ++counters.exceptions;
      ++s.exceptions;
      const std::size_t code = response.size() > 1 ? response[1] : 0;
      ++counters.exception_codes[code < counters.exception_codes.size() ? code : 0];
    }

    s.out.clear();
    encode_adu(frame.header.transaction_id, frame.header.unit_id, response, s.out);
    boost::system::error_code ec;
    const std::size_t written = s.socket.write_some(asio::buffer(s.out), ec);
    if (ec && ec != asio::error::would_block) co_return false;
    if (written < s.out.size()) {
      s.set_deadline(after(options_.request_timeout != Clock::duration::zero()
                               ? options_.request_timeout
                               : options_.idle_timeout));
      auto [write_ec, n] =
          co_await asio::async_write(s.socket, asio::buffer(s.out) + written, use_tuple);
      if (write_ec) co_return false;
    }
    co_return true;
  }

  asio::awaitable<void> watchdog(Session& s) {
    while (Clock::now() < s.deadline) {
      s.timer.expires_at(s.deadline);
      co_await s.timer.async_wait(use_tuple);
      // Cancelled by the || because serve() ended, or woken by set_deadline(). The co_await
      // is bound to a local because GCC 12 miscompiled it inside the if condition (SIGILL).
      const asio::cancellation_state state = co_await asio::this_coro::cancellation_state;
      if (state.cancelled() != asio::cancellation_type::none) co_return;
    }
    s.timed_out = true;
  }

  asio::any_io_executor executor_;
  ModbusTcpServerOptions options_;
  std::shared_ptr<RequestHandler> handler_;
  tcp::acceptor acceptor_;
  asio::steady_timer accept_retry_;
  std::list<std::shared_ptr<Session>> sessions_;
  ModbusTcpServerStats stats_;
  bool started_ = false;
  bool stopped_ = false;
};

ModbusTcpServer::ModbusTcpServer(asio::any_io_executor executor, ModbusTcpServerOptions options,
                                 std::shared_ptr<RequestHandler> handler)
    : impl_(std::make_shared<Impl>(std::move(executor), std::move(options), std::move(handler))) {}

ModbusTcpServer::~ModbusTcpServer() {
  impl_->stop();
}

void ModbusTcpServer::start() {
  impl_->start();
}
void ModbusTcpServer::stop() {
  impl_->stop();
}
void ModbusTcpServer::set_handler(std::shared_ptr<RequestHandler> handler) {
  impl_->set_handler(std::move(handler));
}
bool ModbusTcpServer::reconfigure(ModbusTcpServerOptions options) {
  return impl_->reconfigure(std::move(options));
}
tcp::endpoint ModbusTcpServer::local_endpoint() const {
  return impl_->local_endpoint();
}
const ModbusTcpServerStats& ModbusTcpServer::stats() const {
  return impl_->stats();
}
std::vector<ModbusClientInfo> ModbusTcpServer::clients() const {
  return impl_->clients();
}

}  // namespace fieldgate::modbus
