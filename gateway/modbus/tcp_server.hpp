// Modbus TCP server: one coroutine per client on the caller's io_context, no threads.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/ip/tcp.hpp>

#include "gateway/modbus/request_handler.hpp"

namespace fieldgate::modbus {

// What a new connection does to a server already at max_clients.
enum class WhenFull {
  // Room is made, but a connection that has been answered is never closed for one that has not
  // completed a request:
  // - the oldest connection that never completed a request is closed (evicted, never_spoke);
  // - if every open connection has, the newcomer is let in over the limit on probation: once
  //   its first request is complete, the answered connection most overdue against its own
  //   polling rhythm (silent for more than 4 of its usual intervals, and at least
  //   overdue_floor; 5 overdue_floor for one that sent a single request) is closed (evicted,
  //   overdue) and the request served. If
  //   none is overdue, every open client is working: the newcomer is closed unanswered
  //   (refused, no_idle_client).
  // Connections whose request is being answered are never chosen. A stalled or half-sent
  // socket thus cannot keep a PLC that reconnects from getting in, and peers that connect and
  // say nothing cannot push out a PLC that polls, however fast they come.
  evict_idle,
  // The newcomer is accepted and closed at once (counted as refused).
  refuse,
};

struct ModbusTcpServerOptions {
  // An unspecified IPv6 address ("::") listens dual-stack, IPv4 clients included.
  asio::ip::tcp::endpoint endpoint{asio::ip::tcp::v4(), 502};
  // Open connections at most; see WhenFull for what a further one does. 0 = no limit.
  std::size_t max_clients = 32;
  WhenFull when_full = WhenFull::evict_idle;
  // Open connections per client address at most; a further one from that address is refused,
  // whatever when_full says, so one host cannot take every slot. 0 = no limit.
  std::size_t max_clients_per_address = 0;
  // New connections accepted per second at most, from one client address and from all
  // together (each a token bucket holding two seconds' worth). A connection beyond either is
  // closed at once, before any open connection is looked at; one refused for its address does
  // not count against the total, so one flooding address does not shut out the others.
  // 0 = no limit.
  std::size_t max_connects_per_second_per_address = 0;
  std::size_t max_connects_per_second = 0;
  // An answered connection silent for less than this is never overdue (see WhenFull), whatever
  // its rhythm: it covers a PLC's scan jitter.
  std::chrono::steady_clock::duration overdue_floor = std::chrono::seconds(2);
  // No new request started for this long: the connection is closed. Zero disables.
  std::chrono::steady_clock::duration idle_timeout = std::chrono::seconds(60);
  // A request not completely received, or a reply not completely sent, within this time:
  // the connection is closed. Zero disables.
  std::chrono::steady_clock::duration request_timeout = std::chrono::seconds(5);
  // Asked for each new connection with the peer's address (IPv4-mapped IPv6 addresses are
  // passed as IPv4); false closes it at once (counted as denied). Empty = allow all.
  std::function<bool(const asio::ip::address&)> allow_client;
};

struct FunctionCounters {
  std::uint64_t requests = 0;
  std::uint64_t exceptions = 0;  // exception responses sent
  // The same by exception code (0x01..0x0B; 0 counts any other code).
  std::array<std::uint64_t, 12> exception_codes{};
};

// Why a new connection was closed at once (counted in clients_refused too).
struct RefusedCounters {
  std::uint64_t max_clients = 0;       // full, when_full: refuse
  std::uint64_t per_address = 0;       // max_clients_per_address
  std::uint64_t rate_per_address = 0;  // max_connects_per_second_per_address
  std::uint64_t rate = 0;              // max_connects_per_second
  std::uint64_t no_idle_client = 0;    // full of working clients (evict_idle, on probation)
};

// Why an open connection was closed to make room (counted in clients_evicted too).
struct EvictedCounters {
  std::uint64_t never_spoke = 0;  // had not completed a request
  std::uint64_t overdue = 0;      // silent well beyond its own polling rhythm
};

struct ModbusTcpServerStats {
  std::array<FunctionCounters, 256> functions{};  // indexed by the request's function code
  std::uint64_t clients_connected = 0;            // open now
  std::uint64_t clients_accepted = 0;             // served since start
  std::uint64_t clients_refused = 0;              // closed at once: a client limit reached
  RefusedCounters refused;
  std::uint64_t clients_evicted = 0;  // closed to make room (WhenFull::evict_idle)
  EvictedCounters evicted;
  std::uint64_t clients_denied = 0;     // closed at once: allow_client said no
  std::uint64_t clients_timed_out = 0;  // closed by idle_timeout / request_timeout
  std::uint64_t framing_errors = 0;     // closed: bad MBAP protocol id or length
};

// One open client connection, for the console.
struct ModbusClientInfo {
  std::string address;
  std::uint16_t port = 0;
  std::chrono::steady_clock::duration connected_for{};
  std::chrono::steady_clock::duration idle{};  // since its last complete request
  std::uint64_t requests = 0;
  std::uint64_t exceptions = 0;
};

// Every member function must be called on the executor's thread (as all the daemon is).
class ModbusTcpServer {
 public:
  // Opens, binds and listens at once, so a bad endpoint throws boost::system::system_error
  // here; accepting begins with start(). A null handler answers every request with 0x0A.
  ModbusTcpServer(asio::any_io_executor executor, ModbusTcpServerOptions options,
                  std::shared_ptr<RequestHandler> handler);
  ~ModbusTcpServer();  // stop()
  ModbusTcpServer(const ModbusTcpServer&) = delete;
  ModbusTcpServer& operator=(const ModbusTcpServer&) = delete;

  void start();
  // Closes the listening socket and every client connection. A client whose write is being
  // confirmed keeps its coroutine until the handler finishes; its reply is then dropped.
  void stop();

  // For a reload: new requests use the new handler, requests in progress finish with the old
  // one, and connections stay open.
  void set_handler(std::shared_ptr<RequestHandler> handler);
  // Applies max_clients, the timeouts and allow_client (closing open clients it now denies)
  // without closing the listening socket. The endpoint cannot change that way: returns false
  // and applies nothing if it differs.
  bool reconfigure(ModbusTcpServerOptions options);

  asio::ip::tcp::endpoint local_endpoint() const;
  const ModbusTcpServerStats& stats() const;
  std::vector<ModbusClientInfo> clients() const;

 private:
  class Impl;
  std::shared_ptr<Impl> impl_;  // shared with the client coroutines, which may outlive *this
};

}  // namespace fieldgate::modbus
