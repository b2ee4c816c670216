#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/ip/tcp.hpp>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "gateway/modbus/access_control.hpp"

namespace fieldgate {

namespace asio = boost::asio;

struct MetricsServerStats {
  std::uint64_t accepted = 0;
  std::uint64_t refused = 0;       // closed at once: max_connections were open, none to evict
  std::uint64_t evicted = 0;       // closed while its request had not come, to make room
  std::uint64_t denied = 0;        // closed unanswered: the peer is not on the allow list
  std::uint64_t bad_requests = 0;  // answered 400, 413 or 431: the request could not be parsed
};

// A minimal HTTP/1.1 endpoint (Boost.Beast) answering GET /metrics with the text the callback
// renders, and POST /trace?bus=NAME&on=1 (the wire trace switch); anything else gets 404 or 405,
// and a request that cannot be parsed 400, 413 or 431 (gateway/http/request_reading.hpp). With an
// allow list, a peer off it is closed unanswered. One short-lived coroutine per connection.
class MetricsServer {
 public:
  using Render = std::function<std::string()>;

  // A scraper needs one connection at a time; a few more cover overlapping scrapes. Beyond
  // this, connections are accepted and closed at once, so stalled HTTP clients cannot use up
  // the descriptors the Modbus server needs.
  static constexpr std::size_t max_connections = 8;
  // Reading the request and writing the reply must finish within this, or the connection is
  // closed.
  static constexpr std::chrono::seconds exchange_timeout{2};

  // Binds at once; throws boost::system::system_error if it cannot. An empty allow list lets
  // every peer in.
  MetricsServer(asio::any_io_executor executor, asio::ip::tcp::endpoint endpoint, Render render,
                ClientAllowList allow = {});
  ~MetricsServer();
  void start();
  void stop();
  asio::ip::tcp::endpoint local_endpoint() const;
  const MetricsServerStats& stats() const;
  std::size_t open_connections() const;

  struct State;  // shared with the connection coroutines, which may outlive the server

 private:
  std::shared_ptr<State> state_;
};

}  // namespace fieldgate
