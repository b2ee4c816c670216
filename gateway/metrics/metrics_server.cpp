#include "gateway/metrics/metrics_server.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include "gateway/bus/wire_trace.hpp"

namespace fieldgate {

namespace beast = boost::beast;
namespace http = beast::http;

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
}

struct MetricsServer::State {
  State(asio::any_io_executor ex, asio::ip::tcp::endpoint ep, Render r)
      : acceptor(ex, ep), accept_retry(ex), render(std::move(r)) {}
  asio::ip::tcp::acceptor acceptor;
  asio::steady_timer accept_retry;
  Render render;
  std::size_t open = 0;  // connections being served now
  MetricsServerStats stats;
  bool stopped = false;
};

namespace {

asio::awaitable<void> exchange(beast::tcp_stream& stream, MetricsServer::State& state) {
  beast::flat_buffer buffer(8192);
  http::request_parser<http::empty_body> parser;
  parser.header_limit(8192);
  // One deadline for the whole exchange, reading and writing: a scraper is local and quick.
  stream.expires_after(MetricsServer::exchange_timeout);
  auto [ec, n] = co_await http::async_read(stream, buffer, parser, use_tuple);
  (void)n;
  if (ec) co_return;
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
  auto [wec, wn] = co_await http::async_write(stream, res, use_tuple);
  (void)wec;
  (void)wn;
  beast::error_code ignored;
  stream.socket().shutdown(asio::ip::tcp::socket::shutdown_send, ignored);
}

// The accept loop counted this connection in state->open already.
asio::awaitable<void> serve(beast::tcp_stream stream, std::shared_ptr<MetricsServer::State> state) {
  try {
    co_await exchange(stream, *state);
  } catch (...) {
    // Belongs to this connection alone.
  }
  --state->open;
}

asio::awaitable<void> accept_loop(std::shared_ptr<MetricsServer::State> state) {
  while (!state->stopped) {
    auto [ec, socket] = co_await state->acceptor.async_accept(use_tuple);
    if (state->stopped) co_return;
    if (ec) {
      // E.g. EMFILE: retrying at once would spin; stop() closes the acceptor meanwhile.
      state->accept_retry.expires_after(std::chrono::milliseconds(100));
      co_await state->accept_retry.async_wait(use_tuple);
      continue;
    }
    if (state->open >= MetricsServer::max_connections) {
      // Closed at once: stalled scrapers must not take the descriptors the Modbus server needs.
      ++state->stats.refused;
      continue;
    }
    ++state->stats.accepted;
    ++state->open;
    asio::co_spawn(state->acceptor.get_executor(),
                   serve(beast::tcp_stream(std::move(socket)), state), asio::detached);
  }
}

}  // namespace

MetricsServer::MetricsServer(asio::any_io_executor executor, asio::ip::tcp::endpoint endpoint,
                             Render render)
    : state_(std::make_shared<State>(executor, endpoint, std::move(render))) {}

MetricsServer::~MetricsServer() {
  stop();
}

void MetricsServer::start() {
  asio::co_spawn(state_->acceptor.get_executor(), accept_loop(state_), asio::detached);
}

void MetricsServer::stop() {
  state_->stopped = true;
  boost::system::error_code ignored;
  state_->acceptor.close(ignored);
  state_->accept_retry.cancel();
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
