#include "gateway/metrics/metrics_server.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include "gateway/bus/wire_trace.hpp"
#include "gateway/http/accept_loop.hpp"
#include "gateway/http/request_reading.hpp"

namespace fieldgate {

namespace beast = boost::beast;
namespace http = beast::http;

struct MetricsServer::State {
  State(asio::any_io_executor ex, asio::ip::tcp::endpoint ep, Render r, ClientAllowList a)
      : acceptor(ex, ep), accept_retry(ex), render(std::move(r)), allow(std::move(a)) {}
  asio::ip::tcp::acceptor acceptor;
  asio::steady_timer accept_retry;
  Render render;
  ClientAllowList allow;
  // Closed unanswered, as the Modbus listener does with a client off its allow list.
  bool denies(const asio::ip::address& peer) const { return !allow.allows(peer); }
  HttpConnections connections;
  std::size_t open = 0;  // connections being served now
  MetricsServerStats stats;
  bool stopped = false;
};

namespace {

asio::awaitable<void> exchange(beast::tcp_stream& stream, MetricsServer::State& state,
                               HttpConnection& connection) {
  beast::flat_buffer buffer;
  http_request::Parser parser;
  // One deadline for the whole exchange, reading and writing: a scraper is local and quick.
  const bool request =
      co_await http_request::read_or_answer(stream, buffer, parser, MetricsServer::exchange_timeout,
                                            state.stats.bad_requests, [](auto&) {});
  if (!request) co_return;
  connection.admitted = true;
  const auto& req = parser.get();
  http::response<http::string_body> res;
  res.version(req.version());
  res.keep_alive(false);
  res.set(http::field::server, "fieldgate");
  if (req.method() == http::verb::post && req.target().starts_with("/trace")) {
    const auto r = trace_control(std::string_view(req.target().data(), req.target().size()));
    res.result(static_cast<http::status>(r.status));
    res.set(http::field::content_type, "text/plain; charset=utf-8");
    res.body() = r.body;
  } else if (req.method() != http::verb::get && req.method() != http::verb::head) {
    res.result(http::status::method_not_allowed);
    res.set(http::field::allow, "GET, HEAD");
  } else if (req.target() != "/metrics") {
    res.result(http::status::not_found);
    res.body() = "try /metrics\n";
  } else if (!state.stopped) {
    res.result(http::status::ok);
    res.set(http::field::content_type, "text/plain; version=0.0.4; charset=utf-8");
    res.body() = state.render();
  }
  res.prepare_payload();
  if (req.method() == http::verb::head) res.body().clear();
  co_await http_request::reply_and_finish(stream, res, MetricsServer::exchange_timeout);
}

}  // namespace

MetricsServer::MetricsServer(asio::any_io_executor executor, asio::ip::tcp::endpoint endpoint,
                             Render render, ClientAllowList allow)
    : state_(std::make_shared<State>(executor, endpoint, std::move(render), std::move(allow))) {}

MetricsServer::~MetricsServer() {
  stop();
}

void MetricsServer::start() {
  start_accepting(state_, HttpConnectionLimits{max_connections, 0},
                  [](auto& stream, auto& state, HttpConnection& connection) {
                    return exchange(stream, state, connection);
                  });
}

void MetricsServer::stop() {
  stop_accepting(*state_);
}

const MetricsServerStats& MetricsServer::stats() const {
  return state_->stats;
}

std::size_t MetricsServer::open_connections() const {
  return state_->open;
}

asio::ip::tcp::endpoint MetricsServer::local_endpoint() const {
  return state_->acceptor.local_endpoint();
}

}  // namespace fieldgate
