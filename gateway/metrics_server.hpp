#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/ip/tcp.hpp>

#include <functional>
#include <memory>
#include <string>

namespace fieldgate {

namespace asio = boost::asio;

// A minimal HTTP/1.1 endpoint (Boost.Beast) answering GET /metrics with the text the callback
// renders; anything else gets 404 or 405. One short-lived coroutine per connection.
class MetricsServer {
 public:
  using Render = std::function<std::string()>;

  // Binds at once; throws boost::system::system_error if it cannot.
  MetricsServer(asio::any_io_executor executor, asio::ip::tcp::endpoint endpoint, Render render);
  ~MetricsServer();
  void start();
  void stop();
  asio::ip::tcp::endpoint local_endpoint() const;

  struct State;  // shared with the connection coroutines, which may outlive the server

 private:
  std::shared_ptr<State> state_;
};

}  // namespace fieldgate
