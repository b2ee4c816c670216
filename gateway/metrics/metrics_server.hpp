#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/ip/tcp.hpp>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace fieldgate {

namespace asio = boost::asio;

struct MetricsServerStats {
  std::uint64_t accepted = 0;
  std::uint64_t refused = 0;  // closed at once: max_connections were open
};

// A minimal HTTP/1.1 endpoint (Boost.Beast) answering GET /metrics with the text the callback
// renders, and POST /trace?bus=NAME&on=1 (the wire trace switch); anything else gets 404 or 405.
// One short-lived coroutine per connection.
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

  // Binds at once; throws boost::system::system_error if it cannot.
  MetricsServer(asio::any_io_executor executor, asio::ip::tcp::endpoint endpoint, Render render);
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
