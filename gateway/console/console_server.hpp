#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/ip/tcp.hpp>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "gateway/config/gateway_config.hpp"

namespace fieldgate {

namespace asio = boost::asio;

struct ConsoleServerStats {
  std::uint64_t accepted = 0;
  std::uint64_t requests = 0;
  std::uint64_t refused = 0;          // closed at once: no slot, and none to evict
  std::uint64_t evicted = 0;          // closed before its request had come, to make room
  std::uint64_t bad_requests = 0;     // answered 400, 413 or 431: the request could not be parsed
  std::uint64_t denied = 0;           // 403: address or token
  std::uint64_t streams = 0;          // live streams opened
  std::uint64_t streams_dropped = 0;  // a client that stopped reading was cut off
};

// The web console (docs/console.md): its pages from the binary, GET /api/plant (the plant as
// JSON) and GET /events, a server-sent event stream of the plant twice a second and, with
// ?trace=1, every frame of every bus. Read-only: no
// request changes anything. Runs on the daemon's executor; every connection is bounded in time
// and memory, so browsers, however many or stalled, cannot hold up Modbus service.
class ConsoleServer {
 public:
  using Snapshot = std::function<std::string()>;

  // Beyond max_connections, a newcomer takes the slot of the connection that has waited longest
  // without a request let in (address and token); only if every one has been let in is it
  // closed at once. Beyond ConsoleConfig::max_pending_per_address connections from one address
  // not let in yet, it takes the slot of that address's oldest such one. So clients that hold
  // slots without sending a request, however fast they reconnect, never keep a user with the
  // token out.
  static constexpr std::size_t max_connections = 160;
  static constexpr std::size_t max_streams = 128;
  // A request must arrive, and each write of a reply or event go out, within this.
  static constexpr std::chrono::seconds exchange_timeout{5};
  static constexpr std::chrono::milliseconds plant_interval{500};
  // The plant is rendered at most this often, whatever the number of streams.
  static constexpr std::chrono::milliseconds snapshot_reuse{200};
  static constexpr std::size_t trace_ring = 4000;      // frames kept for late readers
  static constexpr std::size_t trace_per_event = 500;  // frames sent per stream per tick

  // Binds at once, on console_port(config) (the command line's or the environment's port, if
  // given); throws boost::system::system_error if it cannot.
  ConsoleServer(asio::any_io_executor executor, ConsoleConfig config, Snapshot snapshot);
  ~ConsoleServer();
  void start();
  void stop();
  asio::ip::tcp::endpoint local_endpoint() const;
  const ConsoleServerStats& stats() const;

  struct State;  // shared with the connection coroutines, which may outlive the server

 private:
  std::shared_ptr<State> state_;
};

}  // namespace fieldgate
