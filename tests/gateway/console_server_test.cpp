// The console's HTTP side against a fixed plant snapshot: its pages, the JSON, the event
// stream with trace frames, and what it refuses (writes, unknown pages, a client without the
// token or off the allow list).
#include <gtest/gtest.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>

#include <poll.h>

#include <chrono>
#include <future>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "gateway/bus/wire_trace.hpp"
#include "gateway/console/console_access.hpp"
#include "gateway/console/console_port.hpp"
#include "gateway/console/console_server.hpp"
#include "gateway/metrics/metrics_server.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using asio::ip::tcp;

class ConsoleServerTest : public ::testing::Test {
 protected:
  void start(ConsoleConfig config = {}) {
    config.enabled = true;
    config.port = 0;
    server_ = std::make_unique<ConsoleServer>(io_.get_executor(), config,
                                              [] { return std::string(R"({"nodes":[]})"); });
    server_->start();
    port_ = server_->local_endpoint().port();
    thread_ = std::thread([this] { io_.run(); });
  }
  void TearDown() override {
    if (server_) asio::post(io_, [this] { server_->stop(); });
    guard_.reset();
    io_.stop();
    if (thread_.joinable()) thread_.join();
  }

  // One request; the whole reply (the server closes after it).
  std::string request(const std::string& head) {
    asio::io_context io;
    tcp::socket s(io);
    s.connect({asio::ip::make_address("127.0.0.1"), port_});
    asio::write(s, asio::buffer(head + "\r\n"));
    std::string reply;
    boost::system::error_code ec;
    asio::read(s, asio::dynamic_buffer(reply), ec);
    return reply;
  }
  std::string get(const std::string& target, const std::string& headers = "") {
    return request("GET " + target + " HTTP/1.1\r\nHost: x\r\n" + headers);
  }

  // Reads from an open event stream until `text` has come (or 5 s passed).
  static std::string read_until(tcp::socket& s, const std::string& text) {
    std::string got;
    const auto end = std::chrono::steady_clock::now() + 5s;
    char chunk[4096];
    s.non_blocking(true);
    while (got.find(text) == std::string::npos && std::chrono::steady_clock::now() < end) {
      boost::system::error_code ec;
      const auto n = s.read_some(asio::buffer(chunk), ec);
      if (ec == asio::error::would_block) {
        std::this_thread::sleep_for(10ms);
        continue;
      }
      if (ec) break;
      got.append(chunk, n);
    }
    return got;
  }

  asio::io_context io_;
  asio::executor_work_guard<asio::io_context::executor_type> guard_ = asio::make_work_guard(io_);
  std::unique_ptr<ConsoleServer> server_;
  std::thread thread_;
  uint16_t port_ = 0;
};

TEST_F(ConsoleServerTest, ServesItsPagesAndThePlant) {
  start();
  const std::string page = get("/");
  EXPECT_TRUE(page.starts_with("HTTP/1.1 200")) << page.substr(0, 200);
  EXPECT_NE(page.find("Content-Type: text/html"), std::string::npos);
  EXPECT_NE(page.find("<title>fieldgate console</title>"), std::string::npos);
  EXPECT_NE(get("/console.js").find("EventSource"), std::string::npos);
  EXPECT_NE(get("/console.css").find("text/css"), std::string::npos);
  const std::string plant = get("/api/plant");
  EXPECT_NE(plant.find("application/json"), std::string::npos);
  EXPECT_TRUE(plant.ends_with(R"({"nodes":[]})")) << plant;
  EXPECT_NE(plant.find("Cache-Control: no-store"), std::string::npos);
}

TEST_F(ConsoleServerTest, ReadOnlyAndNothingElse) {
  start();
  EXPECT_TRUE(request("POST /api/plant HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n")
                  .starts_with("HTTP/1.1 405"));
  EXPECT_TRUE(get("/trace?on=1").starts_with("HTTP/1.1 404"));
  EXPECT_TRUE(get("/../../etc/passwd").starts_with("HTTP/1.1 404"));
}

TEST_F(ConsoleServerTest, TokenAndAllowList) {
  ConsoleConfig c;
  c.token_sha256 = sha256_hex("s3cret");
  start(c);
  EXPECT_TRUE(get("/api/plant").starts_with("HTTP/1.1 403"));
  EXPECT_NE(get("/api/plant").find("no token"), std::string::npos);
  EXPECT_NE(get("/api/plant?token=guess").find("wrong token"), std::string::npos);
  EXPECT_TRUE(get("/api/plant?token=s3cret").starts_with("HTTP/1.1 200"));
  EXPECT_TRUE(get("/", "Authorization: Bearer s3cret\r\n").starts_with("HTTP/1.1 200"));
  // The page's style and script hold no plant data, and a browser asks for them without the
  // token the page was opened with: they are served; the plant's data is not.
  for (const char* asset : {"/console.css", "/console.js", "/"})
    EXPECT_TRUE(get(asset).starts_with("HTTP/1.1 200")) << asset;
  EXPECT_TRUE(get("/events").starts_with("HTTP/1.1 403"));
}

TEST_F(ConsoleServerTest, AnAddressOffTheAllowListIsRefused) {
  ConsoleConfig c;
  std::string error;
  c.allow = ClientAllowList({*Cidr::parse("10.0.0.0/8", error)});
  start(c);
  const std::string reply = get("/");
  EXPECT_TRUE(reply.starts_with("HTTP/1.1 403")) << reply;
  EXPECT_NE(reply.find("allow list"), std::string::npos);
}

TEST_F(ConsoleServerTest, EventStreamCarriesThePlantAndTraceFrames) {
  start();
  WireTrace trace("bus_a");  // off in the log: the stream still sees its frames
  asio::io_context io;
  tcp::socket s(io);
  s.connect({asio::ip::make_address("127.0.0.1"), port_});
  asio::write(s, asio::buffer(std::string("GET /events?trace=1 HTTP/1.1\r\nHost: x\r\n\r\n")));
  const std::string head = read_until(s, "event: plant");
  EXPECT_NE(head.find("Content-Type: text/event-stream"), std::string::npos) << head;
  EXPECT_NE(head.find(R"(data: {"nodes":[]})"), std::string::npos) << head;
  // The frame is emitted on the server's thread, as a bus would.
  std::promise<bool> observed;
  asio::post(io_, [&] {
    observed.set_value(WireTrace::observed());
    trace.emit(std::chrono::steady_clock::now(), "node_1", TraceDirection::tx, "ok", "AZ\\n");
  });
  EXPECT_TRUE(observed.get_future().get())
      << "a trace viewer is open: the buses' frames are wanted";
  const std::string more = read_until(s, "event: trace");
  EXPECT_NE(more.find(R"("bus":"bus_a","node":"node_1","dir":"tx","outcome":"ok","bytes":"AZ\\n")"),
            std::string::npos)
      << more;
  EXPECT_EQ(trace.lines(), 0u) << "the log trace stays off";
  s.close();
  // The server notices the closed stream at its next write, and stops observing the buses.
  const auto end = std::chrono::steady_clock::now() + 5s;
  bool still = true;
  while (still && std::chrono::steady_clock::now() < end) {
    std::promise<bool> p;
    asio::post(io_, [&] { p.set_value(WireTrace::observed()); });
    still = p.get_future().get();
    if (still) std::this_thread::sleep_for(50ms);
  }
  EXPECT_FALSE(still);
}

// Exactly `bytes` to `port` (from `source`, a loopback address), then everything the server
// sends until it closes.
std::string exchange_raw(std::uint16_t port, const std::string& bytes,
                         const char* source = "127.0.0.1", bool then_shutdown = false) {
  asio::io_context io;
  tcp::socket s(io);
  s.open(tcp::v4());
  s.bind({asio::ip::make_address(source), 0});
  s.connect({asio::ip::make_address("127.0.0.1"), port});
  boost::system::error_code ec;
  asio::write(s, asio::buffer(bytes), ec);
  if (then_shutdown) s.shutdown(tcp::socket::shutdown_send, ec);  // nothing more: no drain wait
  std::string reply;
  asio::read(s, asio::dynamic_buffer(reply), ec);
  return reply;
}

// Requests Beast cannot take, and requests for a method neither server has: each gets a status
// line, never a bare close. The console refuses a method on the request's header, before its
// body: a third status where that gives the console another one.
struct BadRequest {
  std::string request;
  std::string status;
  std::string console_status = status;
};
const std::vector<BadRequest>& bad_requests() {
  static const std::vector<BadRequest> cases = {
      {"GARBAGE\r\n\r\n", "400"},                                 // bad request line
      {"GET / HTTP/1.1\r\nHost x\r\n\r\n", "400"},                // header without colon
      {"GET / HTTP/1.1\r\nHo st: x\r\n\r\n", "400"},              // bad header name
      {"GET / HTTP/1.1\r\nHost: x\r\nX: a\x01b\r\n\r\n", "400"},  // bad header value
      {"GET /\r\n\r\n", "400"},                                   // HTTP/0.9
      {"GET / HTTP/2.5x\r\nHost: x\r\n\r\n", "400"},              // bad version
      {"GET / HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\nxx\r\n",
       "400"},  // chunked garbage
      {"POST / HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n5;\x01\r\n", "400", "405"},
      {"POST / HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\nTransfer-Encoding: chunked\r\n\r\n"
       "5\r\nhello\r\n0\r\n\r\n",
       "400"},  // CL and TE together
      {"GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 1\r\nContent-Length: 2\r\n\r\nab", "400"},
      {"GET / HTTP/1.1\r\nHost: x\r\nContent-Length: -1\r\n\r\n", "400"},
      {"GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(9000, 'a') + "\r\n\r\n", "431"},
      {"POST / HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n" + std::string(1000, 'b'),
       "413", "405"},
      {"GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n" + std::string(1000, 'b'),
       "413"},
      {"POST / HTTP/1.1\r\nHost: x\r\nContent-Length: 11\r\n\r\nhello world", "405"},
      {"POST / HTTP/1.1\r\nHost: x\r\n\r\n", "405"},
      {"PUT /x HTTP/1.1\r\nHost: x\r\nContent-Length: 3\r\n\r\nabc", "405"},
      {"PUT /x HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n3\r\nabc\r\n0\r\n\r\n",
       "405"},
      {"DELETE / HTTP/1.0\r\n\r\n", "405"},
  };
  return cases;
}

TEST_F(ConsoleServerTest, EveryBadRequestGetsAStatusLine) {
  start();
  for (const auto& c : bad_requests()) {
    const std::string& request = c.request;
    const std::string& status = c.console_status;
    const std::string reply = exchange_raw(port_, request);
    EXPECT_TRUE(reply.starts_with("HTTP/1.") && reply.substr(8, 4) == " " + status)
        << request.substr(0, 80) << " -> '" << reply.substr(0, 80) << "'";
  }
  // A request cut off by the peer's shutdown is answered too.
  asio::io_context io;
  tcp::socket s(io);
  s.connect({asio::ip::make_address("127.0.0.1"), port_});
  asio::write(
      s, asio::buffer(std::string("GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 9\r\n\r\nab")));
  s.shutdown(tcp::socket::shutdown_send);
  std::string reply;
  boost::system::error_code ec;
  asio::read(s, asio::dynamic_buffer(reply), ec);
  EXPECT_TRUE(reply.starts_with("HTTP/1.1 400")) << reply;
}

// Issue 52: a POST with a body got no reply at all. The console decides on the request's header
// (address, token, method): 403 without the token or with a wrong one, 405 with it, whatever the
// method and however large the body, which it does not wait for.
TEST_F(ConsoleServerTest, ARequestWithABodyGets403Or405) {
  ConsoleConfig c;
  c.token_sha256 = sha256_hex("s3cret");
  start(c);
  const std::vector<std::string> bodies = {
      "Content-Type: application/x-www-form-urlencoded\r\nContent-Length: 7\r\n\r\nstate=1",
      "Content-Type: application/json\r\nContent-Length: 20000\r\n\r\n" + std::string(20000, 'x'),
      "Transfer-Encoding: chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n",
      // curl's way with a large body: the body only once the server says 100 Continue, or
      // after a second. The answer comes first.
      "Content-Length: 2000000\r\nExpect: 100-continue\r\n\r\n",
  };
  const std::vector<std::pair<std::string, std::string>> tokens = {
      {"", "403"},
      {"Authorization: Bearer guess\r\n", "403"},
      {"Authorization: Bearer s3cret\r\n", "405"}};
  for (const char* method : {"POST", "PUT", "PATCH", "DELETE", "OPTIONS"})
    for (const auto& body : bodies)
      for (const auto& [token, status] : tokens) {
        const auto begin = std::chrono::steady_clock::now();
        const std::string reply = exchange_raw(
            port_, std::string(method) + " /api/plant HTTP/1.1\r\nHost: x\r\n" + token + body,
            "127.0.0.1", true);
        EXPECT_TRUE(reply.starts_with("HTTP/1.1 " + status))
            << method << " " << token << body.substr(0, 60) << " -> '" << reply.substr(0, 80)
            << "'";
        EXPECT_LT(std::chrono::steady_clock::now() - begin, 2s) << "answered on the header";
        EXPECT_EQ(reply.find("Allow: GET, HEAD") != std::string::npos, status == "405");
      }
  // A GET with a small body is served; with a large one, 413.
  EXPECT_TRUE(exchange_raw(port_,
                           "GET /api/plant HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer s3cret\r\n"
                           "Content-Length: 3\r\n\r\nabc")
                  .starts_with("HTTP/1.1 200"));
  EXPECT_TRUE(exchange_raw(port_,
                           "GET /api/plant HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer s3cret\r\n"
                           "Content-Length: 9000\r\n\r\n" +
                               std::string(9000, 'a'))
                  .starts_with("HTTP/1.1 413"));
}

// The console's port from the command line or the environment takes the place of the
// configuration's (main sets it once; a reload keeps it).
TEST_F(ConsoleServerTest, ThePortOverrideTakesThePlaceOfTheConfigurations) {
  asio::io_context io;
  tcp::acceptor probe(io, {asio::ip::make_address("127.0.0.1"), 0});
  const auto wanted = probe.local_endpoint().port();
  probe.close();
  ConsoleConfig c;
  c.port = 9580;
  EXPECT_EQ(console_port(c), 9580);
  set_console_port_override(wanted);
  EXPECT_EQ(console_port(c), wanted);
  ConsoleServer server(io_.get_executor(), c, [] { return std::string("{}"); });
  set_console_port_override(std::nullopt);
  EXPECT_EQ(server.local_endpoint().port(), wanted);
  EXPECT_EQ(console_port(c), 9580);
}

class MetricsServerTest : public ::testing::Test {
 protected:
  void start(ClientAllowList allow = {}) {
    server_ = std::make_unique<MetricsServer>(
        io_.get_executor(), tcp::endpoint(asio::ip::make_address("127.0.0.1"), 0),
        [] { return std::string("fieldgate_up 1\n"); }, std::move(allow));
    server_->start();
    port_ = server_->local_endpoint().port();
    thread_ = std::thread([this] { io_.run(); });
  }
  void TearDown() override {
    if (server_) asio::post(io_, [this] { server_->stop(); });
    guard_.reset();
    io_.stop();
    if (thread_.joinable()) thread_.join();
  }
  MetricsServerStats stats() {
    std::promise<MetricsServerStats> p;
    asio::post(io_, [&] { p.set_value(server_->stats()); });
    return p.get_future().get();
  }

  asio::io_context io_;
  asio::executor_work_guard<asio::io_context::executor_type> guard_ = asio::make_work_guard(io_);
  std::unique_ptr<MetricsServer> server_;
  std::thread thread_;
  uint16_t port_ = 0;
};

TEST_F(MetricsServerTest, EveryBadRequestGetsAStatusLine) {
  start();
  for (const auto& c : bad_requests()) {
    const std::string& request = c.request;
    const std::string& status = c.status;
    const std::string reply = exchange_raw(port_, request);
    EXPECT_TRUE(reply.starts_with("HTTP/1.") && reply.substr(8, 4) == " " + status)
        << request.substr(0, 80) << " -> '" << reply.substr(0, 80) << "'";
  }
  const std::string ok = exchange_raw(port_, "GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_TRUE(ok.starts_with("HTTP/1.1 200")) << ok;
  EXPECT_TRUE(ok.ends_with("fieldgate_up 1\n")) << ok;
  EXPECT_GE(stats().bad_requests, 10u);
}

TEST_F(MetricsServerTest, APeerOffTheAllowListIsClosedUnanswered) {
  std::string error;
  start(ClientAllowList({*Cidr::parse("127.0.0.2/32", error), *Cidr::parse("fd00::/8", error)}));
  const std::string get = "GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n";
  EXPECT_EQ(exchange_raw(port_, get, "127.0.0.1"), "");
  EXPECT_TRUE(exchange_raw(port_, get, "127.0.0.2").starts_with("HTTP/1.1 200"));
  const auto s = stats();
  EXPECT_EQ(s.denied, 1u);
  EXPECT_EQ(s.accepted, 1u);
}

// One client keeps every console slot taken: it holds 200 connections that never finish their
// request and reopens each one the server closes. A user with the token is still answered at
// every request: a newcomer takes the slot of the connection waiting longest without a request
// let in, and the attacker cannot outpace the user's own request.
TEST_F(ConsoleServerTest, ATokenHolderIsAnsweredWhileAReconnectingSlowlorisHoldsTheSlots) {
  ConsoleConfig c;
  c.token_sha256 = sha256_hex("s3cret");
  c.max_pending_per_address = 0;  // the attacker shares the user's address
  start(c);
  std::atomic<bool> attacking{true};
  std::atomic<int> reopened{0};
  std::thread attacker([&] {
    asio::io_context io;
    std::vector<std::unique_ptr<tcp::socket>> held;
    auto open_one = [&] {
      auto s = std::make_unique<tcp::socket>(io);
      boost::system::error_code ec;
      s->connect({asio::ip::make_address("127.0.0.1"), port_}, ec);
      if (!ec) asio::write(*s, asio::buffer(std::string("GET / HTTP/1.1\r\nHost: x\r\n")), ec);
      return s;
    };
    for (int i = 0; i < 200; ++i) held.push_back(open_one());
    while (attacking) {
      std::vector<pollfd> fds;
      for (auto& s : held) fds.push_back({s->native_handle(), POLLIN, 0});
      ::poll(fds.data(), fds.size(), 10);
      for (std::size_t i = 0; i < held.size(); ++i)
        if (fds[i].revents != 0) {  // closed by the server (or refused at once): reopened
          held[i] = open_one();
          ++reopened;
        }
    }
  });
  // The attacker has filled the slots and is reopening what the server closes.
  while (reopened < 50) std::this_thread::sleep_for(10ms);
  int answered = 0;
  for (int i = 0; i < 30; ++i)
    answered += get("/api/plant", "Authorization: Bearer s3cret\r\n").starts_with("HTTP/1.1 200");
  attacking = false;
  attacker.join();
  EXPECT_EQ(answered, 30);
  std::promise<ConsoleServerStats> p;
  asio::post(io_, [&] { p.set_value(server_->stats()); });
  const auto stats = p.get_future().get();
  EXPECT_GT(stats.evicted, 0u);
  EXPECT_EQ(stats.requests, 30u) << "only the user's requests were let in";
}

// From one address at most max_pending_per_address connections wait for their request; live
// views once let in do not count.
TEST_F(ConsoleServerTest, WaitingConnectionsPerAddressAreCapped) {
  ConsoleConfig c;
  c.max_pending_per_address = 4;
  start(c);
  asio::io_context io;
  auto from_2 = [&] {
    auto s = std::make_unique<tcp::socket>(io);
    s->open(tcp::v4());
    s->bind({asio::ip::make_address("127.0.0.2"), 0});
    s->connect({asio::ip::make_address("127.0.0.1"), port_});
    return s;
  };
  std::vector<std::unique_ptr<tcp::socket>> views, silent;
  for (int i = 0; i < 6; ++i) {
    views.push_back(from_2());
    asio::write(*views.back(),
                asio::buffer(std::string("GET /events HTTP/1.1\r\nHost: x\r\n\r\n")));
    EXPECT_NE(read_until(*views.back(), "event: plant").find("event: plant"), std::string::npos);
  }
  for (int i = 0; i < 10; ++i) silent.push_back(from_2());
  auto count_open = [](auto& sockets) {
    int open = 0;
    for (auto& s : sockets) {
      pollfd p{s->native_handle(), POLLIN, 0};
      char byte;
      // Open: nothing to read, or stream data (a view); closed: end of stream.
      open += ::poll(&p, 1, 0) == 0 || ::recv(s->native_handle(), &byte, 1, MSG_PEEK) > 0;
    }
    return open;
  };
  // The address's oldest silent connections made room for its newer ones: 4 stay open.
  const auto end = std::chrono::steady_clock::now() + 5s;
  while (count_open(silent) > 4 && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(10ms);
  EXPECT_EQ(count_open(silent), 4);
  EXPECT_EQ(count_open(views), 6);
  // Another address is not affected.
  EXPECT_TRUE(get("/api/plant").starts_with("HTTP/1.1 200"));
}

}  // namespace
}  // namespace fieldgate
