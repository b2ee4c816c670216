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

#include <chrono>
#include <future>
#include <string>
#include <thread>

#include "gateway/bus/wire_trace.hpp"
#include "gateway/console/console_access.hpp"
#include "gateway/console/console_server.hpp"

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

}  // namespace
}  // namespace fieldgate
