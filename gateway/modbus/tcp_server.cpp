#include "gateway/modbus/tcp_server.hpp"

#include <algorithm>
#include <list>
#include <map>

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
  bool spoke = false;      // a request of it has been complete
  bool probation = false;  // let in over max_clients; settled at its first request
  // Its usual time between requests (smoothed), zero until it has sent two.
  Clock::duration rhythm{};
  bool closing = false;  // evicted or denied; its coroutine has not finished yet
  bool timed_out = false;
  MbapFramer framer;
  std::vector<std::uint8_t> out;
};

// New connections at `rate` per second, refilled continuously; it holds two seconds' worth, so a
// fleet of PLCs reconnecting together after a network outage gets in.
struct ConnectBucket {
  static constexpr double burst_seconds = 2;
  double tokens = 0;
  Clock::time_point at{};

  static double capacity(std::size_t rate) { return burst_seconds * static_cast<double>(rate); }
  double now_holding(std::size_t rate, Clock::time_point now) const {
    if (at == Clock::time_point{}) return capacity(rate);
    return std::min(capacity(rate), tokens + std::chrono::duration<double>(now - at).count() *
                                                 static_cast<double>(rate));
  }
  bool take(std::size_t rate, Clock::time_point now) {
    tokens = now_holding(rate, now);
    at = now;
    if (tokens < 1) return false;
    tokens -= 1;
    return true;
  }
  bool refilled(std::size_t rate, Clock::time_point now) const {
    return now_holding(rate, now) >= capacity(rate);
  }
};

// How long an answered connection may stay silent before it counts as gone: several of its own
// intervals, never less than the floor.
constexpr int overdue_intervals = 4;
constexpr int overdue_single_request = 5;  // floors, for a client with no rhythm yet

Clock::duration overdue_after(const Session& s, Clock::duration floor) {
  if (s.rhythm == Clock::duration::zero()) return overdue_single_request * floor;
  return std::max(floor, overdue_intervals * s.rhythm);
}

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
      if (!within_rate(peer)) {
        ++stats_.clients_refused;
        continue;
      }
      bool probation = false;
      if (!admit(peer, probation)) {
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
      sessions_.back()->probation = probation;
      ++stats_.clients_accepted;
      ++stats_.clients_connected;
      asio::co_spawn(executor_, run_session(self, std::prev(sessions_.end())), asio::detached);
    }
  }

  // The connect rates, checked before any open connection is looked at.
  bool within_rate(const asio::ip::address& peer) {
    const auto now = Clock::now();
    if (const std::size_t rate = options_.max_connects_per_second_per_address; rate != 0) {
      // Addresses whose bucket has refilled are as good as new: dropping them bounds the map.
      if (connect_buckets_.size() > 1024)
        std::erase_if(connect_buckets_,
                      [&](const auto& entry) { return entry.second.refilled(rate, now); });
      if (!connect_buckets_[peer].take(rate, now)) {
        ++stats_.refused.rate_per_address;
        return false;
      }
    }
    if (const std::size_t rate = options_.max_connects_per_second; rate != 0) {
      if (!connect_bucket_.take(rate, now)) {
        ++stats_.refused.rate;
        return false;
      }
    }
    return true;
  }

  // Whether a new connection from `peer` may be served, making room first if the policy says
  // so; `probation` is set when it is let in over max_clients (see WhenFull::evict_idle).
  bool admit(const asio::ip::address& peer, bool& probation) {
    std::size_t open = 0;
    std::size_t from_peer = 0;
    std::shared_ptr<Session> silent;  // the oldest that never completed a request
    for (const auto& session : sessions_) {
      if (session->closing) continue;
      ++open;
      if (session->peer == peer) ++from_peer;
      if (!session->spoke && !session->answering &&
          (!silent || session->connected_at < silent->connected_at))
        silent = session;
    }
    if (options_.max_clients_per_address != 0 && from_peer >= options_.max_clients_per_address) {
      ++stats_.refused.per_address;
      return false;
    }
    if (options_.max_clients == 0 || open < options_.max_clients) return true;
    if (options_.when_full == WhenFull::refuse) {
      ++stats_.refused.max_clients;
      return false;
    }
    if (silent) {
      evict(*silent);
      ++stats_.evicted.never_spoke;
      return true;
    }
    // Every open connection has been answered: none is closed for a newcomer that has not
    // completed a request yet. Any earlier probationer has spoken, and so is settled.
    probation = true;
    return true;
  }

  void evict(Session& s) {
    s.closing = true;
    s.close();
    ++stats_.clients_evicted;
  }

  // A probationer's first request is complete: the most overdue answered connection makes
  // room for it, or, if every client is working, it goes. False: it is to be closed.
  bool settle(Session& newcomer) {
    newcomer.probation = false;
    const auto now = Clock::now();
    std::size_t open = 0;
    Session* overdue = nullptr;
    double worst = 0;
    for (const auto& session : sessions_) {
      if (session->closing) continue;
      ++open;
      if (session.get() == &newcomer || session->answering || !session->spoke) continue;
      const auto idle = now - session->last_request;
      const auto limit = std::max<Clock::duration>(overdue_after(*session, options_.overdue_floor),
                                                   std::chrono::milliseconds(1));
      if (idle <= limit) continue;
      const double ratio = std::chrono::duration<double>(idle).count() /
                           std::chrono::duration<double>(limit).count();
      if (!overdue || ratio > worst) {
        overdue = session.get();
        worst = ratio;
      }
    }
    // Someone left meanwhile, or the limit was raised by a reload.
    if (options_.max_clients == 0 || open <= options_.max_clients) return true;
    if (!overdue) {
      ++stats_.refused.no_idle_client;
      ++stats_.clients_refused;
      return false;
    }
    evict(*overdue);
    ++stats_.evicted.overdue;
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
        const auto now = Clock::now();
        if (s.probation && !settle(s)) co_return;
        if (s.spoke) {
          const auto interval = now - s.last_request;
          s.rhythm = s.rhythm == Clock::duration::zero() ? interval : (7 * s.rhythm + interval) / 8;
        }
        s.spoke = true;
        s.last_request = now;
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
  std::map<asio::ip::address, ConnectBucket> connect_buckets_;
  ConnectBucket connect_bucket_;
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
