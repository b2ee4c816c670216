#pragma once

// Reading one request and answering it on the daemon's small HTTP servers (metrics, console):
// Boost.Beast parses the whole request under the limits below, and every request it cannot
// take gets the status its parser error stands for before the connection is closed, instead
// of a bare close.

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace fieldgate::http_request {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;

// Request line and headers together; beyond it 431.
inline constexpr std::size_t header_limit = 8192;
// No request needs a body; a small one (a form sent along with a POST) is read and ignored so
// the reply is not lost to a reset, a larger one gets 413. (The console refuses a request on its
// header, before its body: read_header_or_answer.)
inline constexpr std::size_t body_limit = 8192;

using Parser = http::request_parser<http::string_body>;

// The status for a request the parser refused; nullopt where there is no request to answer:
// the peer sent nothing or went away, the deadline passed (the stream is closed then), or a
// socket error.
inline std::optional<http::status> status_for(const beast::error_code& ec, const Parser& parser) {
  if (ec.category() != http::make_error_code(http::error::bad_method).category())
    return std::nullopt;
  switch (static_cast<http::error>(ec.value())) {
    case http::error::end_of_stream:  // closed before a byte of the next request
      return std::nullopt;
    case http::error::header_limit:
      return http::status::request_header_fields_too_large;
    case http::error::body_limit:
      return http::status::payload_too_large;
    case http::error::buffer_overflow:
      return parser.is_header_done() ? http::status::payload_too_large
                                     : http::status::request_header_fields_too_large;
    default:
      // bad_method, bad_target, bad_version (HTTP/0.9 included), bad_line_ending, bad_field,
      // bad_value, bad_content_length, bad_transfer_encoding (Content-Length with chunked),
      // multiple_content_length, bad_chunk, bad_chunk_extension, bad_obs_fold, and
      // partial_message (the peer ended its side mid-request).
      return http::status::bad_request;
  }
}

// The limits every request is read under.
inline void set_limits(Parser& parser) {
  parser.header_limit(header_limit);
  parser.body_limit(body_limit);
}

// Reads one request within `timeout`. On failure returns the error; `parser` tells how far it
// got.
inline asio::awaitable<beast::error_code> read(beast::tcp_stream& stream,
                                               beast::flat_buffer& buffer, Parser& parser,
                                               std::chrono::steady_clock::duration timeout) {
  set_limits(parser);
  stream.expires_after(timeout);
  auto [ec, n] =
      co_await http::async_read(stream, buffer, parser, asio::as_tuple(asio::use_awaitable));
  (void)n;
  co_return ec;
}

// Reads the request line and headers only, within `timeout`: a server may refuse a request on
// them (its method, its token) without taking its body. read_rest then reads the body.
inline asio::awaitable<beast::error_code> read_header(beast::tcp_stream& stream,
                                                      beast::flat_buffer& buffer, Parser& parser,
                                                      std::chrono::steady_clock::duration timeout) {
  parser.header_limit(header_limit);
  // Beast weighs a Content-Length against the body limit as the header ends: read_rest does.
  parser.body_limit(boost::none);
  stream.expires_after(timeout);
  auto [ec, n] =
      co_await http::async_read_header(stream, buffer, parser, asio::as_tuple(asio::use_awaitable));
  (void)n;
  co_return ec;
}

// Reads the body of a request whose header read_header took, within what is left of its
// deadline, under body_limit (a Content-Length beyond it is refused before a byte is read).
inline asio::awaitable<beast::error_code> read_rest(beast::tcp_stream& stream,
                                                    beast::flat_buffer& buffer, Parser& parser) {
  parser.body_limit(body_limit);
  const auto length = parser.content_length();
  if (length && *length > body_limit) co_return http::make_error_code(http::error::body_limit);
  auto [ec, n] =
      co_await http::async_read(stream, buffer, parser, asio::as_tuple(asio::use_awaitable));
  (void)n;
  co_return ec;
}

// A reply of its own for a request that could not be taken (no request object to echo).
inline http::response<http::string_body> error_response(http::status status) {
  http::response<http::string_body> res{status, 11};
  res.keep_alive(false);
  res.set(http::field::server, "fieldgate");
  res.set(http::field::content_type, "text/plain; charset=utf-8");
  res.body() = std::string(http::obsolete_reason(status)) + "\n";
  res.prepare_payload();
  return res;
}

// Ends the connection after a reply: our side is shut down, then what the peer still sends is
// read and dropped (briefly, and a bounded amount), so that closing with unread data does not
// reset the connection before the peer has read the reply.
inline asio::awaitable<void> finish(beast::tcp_stream& stream) {
  beast::error_code ignored;
  stream.socket().shutdown(asio::ip::tcp::socket::shutdown_send, ignored);
  stream.expires_after(std::chrono::milliseconds(500));
  std::array<char, 4096> scratch{};
  for (std::size_t drained = 0; drained < 65536;) {
    auto [ec, n] =
        co_await stream.async_read_some(asio::buffer(scratch), asio::as_tuple(asio::use_awaitable));
    if (ec) break;
    drained += n;
  }
  stream.socket().close(ignored);
}

// Writes `res` and ends the connection.
template <typename Body>
asio::awaitable<void> reply_and_finish(beast::tcp_stream& stream, http::response<Body>& res,
                                       std::chrono::steady_clock::duration timeout) {
  stream.expires_after(timeout);
  auto [ec, n] = co_await http::async_write(stream, res, asio::as_tuple(asio::use_awaitable));
  (void)n;
  if (!ec) co_await finish(stream);
}

// After a read that failed with `ec`: the status its error stands for, if there is a request
// to answer (counted in `bad_requests`, with the headers `decorate` adds), and the connection
// ends.
template <typename Decorate>
asio::awaitable<void> answer_refused(beast::tcp_stream& stream, const beast::error_code& ec,
                                     const Parser& parser,
                                     std::chrono::steady_clock::duration timeout,
                                     std::uint64_t& bad_requests, Decorate decorate) {
  const auto status = status_for(ec, parser);
  if (!status) co_return;
  ++bad_requests;
  auto res = error_response(*status);
  decorate(res);
  co_await reply_and_finish(stream, res, timeout);
}

// Reads one request within `timeout`; true when there is one to serve. A request the parser
// refused gets the status its error stands for (answer_refused) and the connection ends; false
// then, as when there is nothing to answer.
template <typename Decorate>
asio::awaitable<bool> read_or_answer(beast::tcp_stream& stream, beast::flat_buffer& buffer,
                                     Parser& parser, std::chrono::steady_clock::duration timeout,
                                     std::uint64_t& bad_requests, Decorate decorate) {
  const auto ec = co_await read(stream, buffer, parser, timeout);
  if (!ec) co_return true;
  co_await answer_refused(stream, ec, parser, timeout, bad_requests, decorate);
  co_return false;
}

// As read_or_answer, for the request line and headers alone (read_header).
template <typename Decorate>
asio::awaitable<bool> read_header_or_answer(beast::tcp_stream& stream, beast::flat_buffer& buffer,
                                            Parser& parser,
                                            std::chrono::steady_clock::duration timeout,
                                            std::uint64_t& bad_requests, Decorate decorate) {
  const auto ec = co_await read_header(stream, buffer, parser, timeout);
  if (!ec) co_return true;
  co_await answer_refused(stream, ec, parser, timeout, bad_requests, decorate);
  co_return false;
}

// As read_or_answer, for the body of a request whose header read_header_or_answer took.
template <typename Decorate>
asio::awaitable<bool> read_rest_or_answer(beast::tcp_stream& stream, beast::flat_buffer& buffer,
                                          Parser& parser,
                                          std::chrono::steady_clock::duration timeout,
                                          std::uint64_t& bad_requests, Decorate decorate) {
  const auto ec = co_await read_rest(stream, buffer, parser);
  if (!ec) co_return true;
  co_await answer_refused(stream, ec, parser, timeout, bad_requests, decorate);
  co_return false;
}

}  // namespace fieldgate::http_request
