// The metrics and console servers' request reading (gateway/http/request_reading.hpp): one
// connection's bytes, arriving in pieces of a fuzzer-chosen size and ended by the peer's
// shutdown, read request after request with Beast's parser under the servers' limits. A request
// the parser takes is within the limits; one it refuses gets a status line (400, 413, 431)
// unless the peer sent nothing more at all.
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/beast/_experimental/test/stream.hpp>

#include <string>

#include "fuzz/fuzz_input.hpp"
#include "gateway/http/request_reading.hpp"

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace reading = fieldgate::http_request;

constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
// Requests read from one connection at most (keep-alive).
constexpr int kMaxRequests = 8;

asio::awaitable<void> serve(beast::test::stream& server, beast::test::stream& client) {
  beast::flat_buffer buffer;
  for (int i = 0; i < kMaxRequests; ++i) {
    reading::Parser parser;
    reading::set_limits(parser);
    auto [ec, n] = co_await http::async_read(server, buffer, parser, use_tuple);
    if (ec) {
      const auto status = reading::status_for(ec, parser);
      // Nothing but the parser fails on this stream: only a connection that ended between
      // requests goes unanswered.
      FUZZ_CHECK(status.has_value() == (ec != http::error::end_of_stream));
      if (!status) co_return;
      FUZZ_CHECK(*status == http::status::bad_request ||
                 *status == http::status::payload_too_large ||
                 *status == http::status::request_header_fields_too_large);
      auto res = reading::error_response(*status);
      auto [write_ec, written] = co_await http::async_write(server, res, use_tuple);
      FUZZ_CHECK(!write_ec);
      const std::string line = "HTTP/1.1 " + std::to_string(static_cast<unsigned>(*status)) + " ";
      const auto sent = client.str();
      FUZZ_CHECK(sent.size() >= written && sent.substr(sent.size() - written, line.size()) == line);
      co_return;
    }
    FUZZ_CHECK(parser.is_done());
    FUZZ_CHECK(n <= reading::header_limit + reading::body_limit + 64 * 1024);
    FUZZ_CHECK(parser.get().body().size() <= reading::body_limit);
    if (!parser.get().keep_alive()) co_return;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fieldgate::fuzz::Input input(data, size);
  const std::size_t piece = 1 + input.byte() % 128;  // bytes per read of the socket
  // The rest sent up to four times over: past the 8 KiB limits within the smoke run's 4 KiB
  // inputs (a header line repeated into 431, a body into 413).
  const int times = 1 + input.byte() % 4;
  std::string sent;
  for (int i = 0; i < times; ++i) sent += input.rest();

  asio::io_context io;
  beast::test::stream server(io);
  beast::test::stream client(io);
  server.connect(client);
  server.read_size(piece);
  server.append(sent);
  server.close_remote();  // the peer shuts its side once it has sent everything
  bool ended = false;
  asio::co_spawn(io, serve(server, client), [&ended](std::exception_ptr e) {
    FUZZ_CHECK(!e);
    ended = true;
  });
  io.run();
  FUZZ_CHECK(ended);
  return 0;
}
