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
  // The open connection that has gone longest without a complete request (since it connected,
  // if it never sent one) is closed to make room (counted as evicted). Connections whose
  // request is being answered are never chosen; if every one is, the newcomer is refused. A
  // stalled or half-sent socket thus cannot keep a PLC that reconnects from getting in.
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

struct ModbusTcpServerStats {
  std::array<FunctionCounters, 256> functions{};  // indexed by the request's function code
  std::uint64_t clients_connected = 0;            // open now
  std::uint64_t clients_accepted = 0;             // served since start
  std::uint64_t clients_refused = 0;              // closed at once: a client limit reached
  std::uint64_t clients_evicted = 0;              // closed to make room (WhenFull::evict_idle)
  std::uint64_t clients_denied = 0;               // closed at once: allow_client said no
  std::uint64_t clients_timed_out = 0;            // closed by idle_timeout / request_timeout
  std::uint64_t framing_errors = 0;               // closed: bad MBAP protocol id or length
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
