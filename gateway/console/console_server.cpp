#include "gateway/console/console_server.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/json.hpp>

#include <deque>

#include "gateway/bus/wire_trace.hpp"
#include "gateway/console/console_access.hpp"
#include "gateway/console/console_assets.hpp"
#include "gateway/console/console_port.hpp"
#include "gateway/http/accept_loop.hpp"
#include "gateway/http/request_reading.hpp"
#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

namespace beast = boost::beast;
namespace http = beast::http;
namespace json = boost::json;

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
using Clock = std::chrono::steady_clock;

// A frame as the page takes it, serialized once however many streams send it.
struct TraceEntry {
  std::uint64_t seq = 0;
  std::string json;
};
}  // namespace

struct ConsoleServer::State : std::enable_shared_from_this<ConsoleServer::State> {
  State(asio::any_io_executor ex, ConsoleConfig c, Snapshot s)
      : acceptor(ex, asio::ip::tcp::endpoint(asio::ip::make_address(c.address), console_port(c))),
        accept_retry(ex),
        config(std::move(c)),
        snapshot(std::move(s)) {}

  // The plant, rendered at most every snapshot_reuse for all streams together.
  const std::string& plant() {
    const auto now = Clock::now();
    if (!cached_at || now - *cached_at >= snapshot_reuse) {
      cached = snapshot();
      cached_at = now;
    }
    return cached;
  }

  // Frames are taken from the buses only while a stream shows them.
  void watch_trace(bool on) {
    if (stopped) return;  // stop() let go of the buses' frames already
    trace_streams += on ? 1 : -1;
    if (trace_streams > 0 && !WireTrace::observed()) {
      std::weak_ptr<State> weak = shared_from_this();
      WireTrace::set_observer([weak](const TraceFrame& f) {
        if (auto s = weak.lock()) s->record(f);
      });
    } else if (trace_streams == 0) {
      WireTrace::set_observer({});
    }
  }

  void record(const TraceFrame& f) {
    const auto wall =
        std::chrono::system_clock::now() -
        std::chrono::duration_cast<std::chrono::system_clock::duration>(Clock::now() - f.at);
    json::object o;
    o["t"] = static_cast<double>(
                 std::chrono::duration_cast<std::chrono::microseconds>(wall.time_since_epoch())
                     .count()) /
             1000.0;
    o["bus"] = f.bus;
    o["node"] = f.node.empty() ? std::string_view("-") : f.node;
    o["dir"] = f.direction == TraceDirection::tx ? "tx" : "rx";
    o["outcome"] = f.outcome.empty() ? std::string_view("-") : f.outcome;
    o["bytes"] = f.bytes;
    if (!f.label.empty()) o["label"] = f.label;
    TraceEntry e{next_seq++, json::serialize(o)};
    trace.push_back(std::move(e));
    while (trace.size() > trace_ring) trace.pop_front();
  }

  asio::ip::tcp::acceptor acceptor;
  asio::steady_timer accept_retry;
  ConsoleConfig config;
  Snapshot snapshot;
  HttpConnections connections;
  std::size_t open = 0;     // connections being served now
  std::size_t streams = 0;  // of them, event streams
  int trace_streams = 0;
  ConsoleServerStats stats;
  bool stopped = false;
  std::string cached;
  std::optional<Clock::time_point> cached_at;
  std::deque<TraceEntry> trace;
  std::uint64_t next_seq = 0;
};

namespace {

template <typename Response>
void common_headers(Response& res) {
  res.set(http::field::server, "fieldgate");
  res.set(http::field::cache_control, "no-store");
  res.set("X-Content-Type-Options", "nosniff");
  res.set("Content-Security-Policy",
          "default-src 'self'; img-src 'self' data:; object-src 'none'; frame-ancestors 'none'");
}

// The frames a stream has not seen yet, as one `trace` event; empty when there are none.
std::string trace_event(ConsoleServer::State& state, std::uint64_t& next) {
  std::uint64_t dropped = 0;
  if (!state.trace.empty() && next < state.trace.front().seq) {
    dropped = state.trace.front().seq - next;
    next = state.trace.front().seq;
  }
  std::string frames;
  std::size_t count = 0;
  if (!state.trace.empty() && next >= state.trace.front().seq) {
    for (std::size_t i = next - state.trace.front().seq;
         i < state.trace.size() && count < ConsoleServer::trace_per_event; ++i, ++count) {
      if (count > 0) frames += ',';
      frames += state.trace[i].json;
      next = state.trace[i].seq + 1;
    }
  }
  if (count == 0 && dropped == 0) return {};
  return "event: trace\ndata: {\"dropped\":" + std::to_string(dropped) + ",\"frames\":[" + frames +
         "]}\n\n";
}

asio::awaitable<void> stream_events(beast::tcp_stream& stream, ConsoleServer::State& state,
                                    unsigned version, bool with_trace) {
  http::response<http::empty_body> res{http::status::ok, version};
  common_headers(res);
  res.set(http::field::content_type, "text/event-stream");
  res.keep_alive(false);
  http::response_serializer<http::empty_body> header(res);
  stream.expires_after(ConsoleServer::exchange_timeout);
  if (auto [ec, n] = co_await http::async_write_header(stream, header, use_tuple); ec) co_return;
  // A new trace viewer starts with the last few frames, so the page is not empty.
  std::uint64_t next = state.next_seq > 200 ? state.next_seq - 200 : 0;
  asio::steady_timer tick(stream.get_executor());
  std::string out = "retry: 2000\n\n";
  while (!state.stopped) {
    out += "event: plant\ndata: " + state.plant() + "\n\n";
    if (with_trace) out += trace_event(state, next);
    stream.expires_after(ConsoleServer::exchange_timeout);
    auto [ec, n] = co_await asio::async_write(stream, asio::buffer(out), use_tuple);
    (void)n;
    if (ec) {
      // A browser that stopped reading (a stalled tab): cut off, its memory freed.
      if (ec == beast::error::timeout) ++state.stats.streams_dropped;
      co_return;
    }
    out.clear();
    tick.expires_after(ConsoleServer::plant_interval);
    co_await tick.async_wait(use_tuple);
  }
}

std::string_view path_of(std::string_view target) {
  return target.substr(0, target.find('?'));
}

asio::awaitable<void> exchange(beast::tcp_stream& stream, ConsoleServer::State& state,
                               HttpConnection& connection) {
  beast::flat_buffer buffer;
  http_request::Parser parser;
  const auto decorate = [](http::response<http::string_body>& res) { common_headers(res); };
  // The header alone decides a refusal (address, token, method): a request refused is answered
  // 403 or 405 whatever its body, which is not read (curl's Expect: 100-continue gets the
  // answer before it sends one).
  const bool request = co_await http_request::read_header_or_answer(
      stream, buffer, parser, ConsoleServer::exchange_timeout, state.stats.bad_requests, decorate);
  if (!request) co_return;
  ++state.stats.requests;
  const auto& req = parser.get();  // its header; the body follows only for a request served
  const std::string_view target(req.target().data(), req.target().size());
  const std::string_view path = path_of(target);
  http::response<http::string_body> res;
  res.version(req.version());
  res.keep_alive(false);
  common_headers(res);
  res.set(http::field::content_type, "text/plain; charset=utf-8");

  boost::system::error_code peer_ec;
  const auto peer = stream.socket().remote_endpoint(peer_ec).address();
  const auto authorization = req[http::field::authorization];
  auto access = peer_ec ? ConsoleAccess::address_refused
                        : check_console_access(
                              state.config, peer,
                              request_token({authorization.data(), authorization.size()}, target));
  // The page, its script and its style hold no plant data: the token guards /api/plant and
  // /events, which the page asks with the token it was opened with. A browser loads the style
  // and the script without it (found on the demo in QEMU, whose console has a token).
  const ConsoleAsset* asset = find_console_asset(path);
  if (asset && (access == ConsoleAccess::token_missing || access == ConsoleAccess::token_wrong))
    access = ConsoleAccess::allowed;
  connection.admitted = access == ConsoleAccess::allowed;
  const bool head = req.method() == http::verb::head;
  const bool readable = req.method() == http::verb::get || head;
  if (access == ConsoleAccess::allowed && readable) {
    // A GET or HEAD with a body: the body is read (and ignored) under the limits.
    const bool whole = co_await http_request::read_rest_or_answer(
        stream, buffer, parser, ConsoleServer::exchange_timeout, state.stats.bad_requests,
        decorate);
    if (!whole) co_return;
  }
  if (access != ConsoleAccess::allowed) {
    ++state.stats.denied;
    res.result(http::status::forbidden);
    res.body() =
        std::string("fieldgate console: ") + std::string(to_string(access)) +
        (access == ConsoleAccess::token_missing ? " (open the page with ?token=...)" : "") + "\n";
  } else if (!readable) {
    // Read-only: nothing on the console changes the plant.
    res.result(http::status::method_not_allowed);
    res.set(http::field::allow, "GET, HEAD");
    res.body() = "the console is read-only\n";
  } else if (path == "/events" && !head) {
    if (state.streams >= ConsoleServer::max_streams) {
      res.result(http::status::service_unavailable);
      res.set(http::field::retry_after, "5");
      res.body() = "too many live views open\n";
    } else {
      const bool with_trace = query_parameter(target, "trace") == "1";
      ++state.streams;
      ++state.stats.streams;
      if (with_trace) state.watch_trace(true);
      co_await stream_events(stream, state, req.version(), with_trace);
      if (with_trace) state.watch_trace(false);
      --state.streams;
      co_return;
    }
  } else if (path == "/api/plant") {
    res.result(http::status::ok);
    res.set(http::field::content_type, "application/json");
    res.body() = state.plant();
  } else if (asset) {
    res.result(http::status::ok);
    res.set(http::field::content_type, std::string(asset->content_type));
    res.body() = std::string(asset->body);
  } else {
    res.result(http::status::not_found);
    res.body() = "no such page; the console is at /\n";
  }
  res.prepare_payload();
  if (head) res.body().clear();
  co_await http_request::reply_and_finish(stream, res, ConsoleServer::exchange_timeout);
}

}  // namespace

ConsoleServer::ConsoleServer(asio::any_io_executor executor, ConsoleConfig config,
                             Snapshot snapshot)
    : state_(std::make_shared<State>(executor, std::move(config), std::move(snapshot))) {}

ConsoleServer::~ConsoleServer() {
  stop();
}

void ConsoleServer::start() {
  start_accepting(state_,
                  HttpConnectionLimits{max_connections, state_->config.max_pending_per_address},
                  [](auto& stream, auto& state, HttpConnection& connection) {
                    return exchange(stream, state, connection);
                  });
}

void ConsoleServer::stop() {
  if (state_->stopped) return;
  stop_accepting(*state_);
  if (state_->trace_streams > 0) WireTrace::set_observer({});
  state_->trace_streams = 0;
}

const ConsoleServerStats& ConsoleServer::stats() const {
  return state_->stats;
}

asio::ip::tcp::endpoint ConsoleServer::local_endpoint() const {
  return state_->acceptor.local_endpoint();
}

}  // namespace fieldgate
