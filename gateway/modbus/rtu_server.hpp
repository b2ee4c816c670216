// Modbus RTU server (slave) on a serial port: frames by the silent interval, answers through
// the same dispatch()/RequestHandler as the TCP server, on the caller's io_context.
//
// RTU is half-duplex with one master, which waits for an answer only until its response
// timeout and then goes on with the next request. A confirmed write can take longer than
// that, so the server never blocks the line on one:
// - Each request is answered only while it is the master's latest frame: once anything else
//   has arrived on the line (another request, another slave's traffic, even garbage), an
//   answer still being worked out is dropped, never sent late where the master would take it
//   for the answer to a later request. The write itself still completes on the field bus.
// - An answer must be sent before the master gives up (response_timeout, minus a guard); with
//   SlowWrites::acknowledge a write still unconfirmed then is answered with exception 0x05
//   (acknowledge: accepted, still running; the spec's answer for exactly this), with
//   SlowWrites::silent it gets no answer.
// - A repeat of a write whose answer the master has not received (same unit, same PDU bytes)
//   while it is still running is the master's retry: it is attached to the running write,
//   never started twice (a relative move must not run twice).
// - Requests for other units are left to the other slaves on the line: no answer.
// - Broadcasts (unit 0) are never answered. Only the configured stop (a write of `value` to
//   holding register `address`) is carried out, as writes to each unit; anything else is
//   dropped and counted.
#pragma once

#include <array>
#include <bitset>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <boost/asio/any_io_executor.hpp>

#include "gateway/modbus/request_handler.hpp"
#include "gateway/modbus/tcp_server.hpp"

namespace fieldgate::modbus {

struct RtuSerialSettings {
  std::string device;
  unsigned baud = 19200;
  unsigned data_bits = 8;
  char parity = 'E';  // N, E, O; the spec's default is even
  unsigned stop_bits = 1;

  unsigned bits_per_character() const {
    return 1 + data_bits + (parity == 'N' ? 0 : 1) + stop_bits;
  }
  bool operator==(const RtuSerialSettings&) const = default;
};

// Kernel RS-485 direction control (TIOCSRS485): the driver switches the transceiver by RTS.
struct Rs485Settings {
  bool enabled = false;
  bool rts_high_on_send = true;  // RTS level while sending; the opposite after
  std::chrono::milliseconds delay_before_send{0};
  std::chrono::milliseconds delay_after_send{0};
  bool operator==(const Rs485Settings&) const = default;
};

enum class SlowWrites { acknowledge, silent };

// A broadcast write of `value` to holding register `address` becomes a write of each entry's
// value to the same register of its unit (each unit's own stop action code).
struct BroadcastStop {
  struct Write {
    std::uint8_t unit;
    std::uint16_t value;
  };
  std::uint16_t address = 100;
  std::uint16_t value = 0xFFFF;
  std::vector<Write> writes;  // empty: every broadcast is dropped
};

struct ModbusRtuServerOptions {
  using Duration = std::chrono::steady_clock::duration;
  RtuSerialSettings serial;
  Rs485Settings rs485;
  Duration frame_gap{0};  // silence that ends a frame; zero: t3.5 from the baud rate
  // A frame whose own length fields say bytes are missing is given this long after its last
  // byte before it is dropped as truncated: USB adapters and loaded hosts deliver a frame's
  // bytes with gaps longer than t3.5. Never shorter than the frame gap.
  Duration incomplete_frame_wait = std::chrono::milliseconds(20);
  // What the master waits for an answer; answers are sent by response_timeout - guard, the
  // guard being a tenth of it (at least 5 ms and the answer's first character).
  Duration response_timeout = std::chrono::seconds(1);
  SlowWrites slow_writes = SlowWrites::acknowledge;
  std::bitset<256> units;  // the unit IDs served here; frames for others are not answered
  BroadcastStop broadcast;
  Duration reopen_min = std::chrono::milliseconds(500);
  Duration reopen_max = std::chrono::seconds(10);
  // Reports: the port opened or failed, broadcast writes that failed.
  std::function<void(const std::string&)> notice;
  std::function<void(const std::string&)> warning;
  // Each dropped frame, for a verbose log.
  std::function<void(const std::string&)> debug;

  Duration silent_interval() const;
  Duration answer_window() const;
};

struct ModbusRtuServerStats {
  std::array<FunctionCounters, 256> functions{};  // requests to this server's units
  std::array<std::uint64_t, 256> exceptions_by_code{};
  std::uint64_t frames_ok = 0;       // good CRC, for a unit served here
  std::uint64_t crc_errors = 0;      // dropped, no answer
  std::uint64_t framing_errors = 0;  // too short, too long or truncated; dropped
  std::uint64_t other_units = 0;     // good frames for units not served here
  std::uint64_t broadcasts_accepted = 0;
  std::uint64_t broadcasts_dropped = 0;
  std::uint64_t broadcast_write_failures = 0;
  std::uint64_t acknowledged = 0;     // slow writes answered with 0x05
  std::uint64_t answers_dropped = 0;  // ready after the master moved on or gave up
  std::uint64_t retries_joined = 0;   // repeats attached to a write still running
  std::uint64_t bytes_received = 0;
  std::uint64_t bytes_sent = 0;
  std::uint64_t opens = 0;
  bool link_up = false;
};

// Every member function must be called on the executor's thread.
class ModbusRtuServer {
 public:
  // Nothing is opened until start(); the port is then opened and reopened with back-off
  // whenever it fails (a USB adapter unplugged). A null handler answers 0x0A.
  ModbusRtuServer(asio::any_io_executor executor, ModbusRtuServerOptions options,
                  std::shared_ptr<RequestHandler> handler);
  ~ModbusRtuServer();  // stop()
  ModbusRtuServer(const ModbusRtuServer&) = delete;
  ModbusRtuServer& operator=(const ModbusRtuServer&) = delete;

  void start();
  void stop();
  // As ModbusTcpServer::set_handler: requests in progress finish with the old handler.
  void set_handler(std::shared_ptr<RequestHandler> handler);
  // Applies everything but the port's settings; returns false and applies nothing if the
  // serial or RS-485 settings differ (the caller makes a new server).
  bool reconfigure(ModbusRtuServerOptions options);

  const ModbusRtuServerOptions& options() const;
  const ModbusRtuServerStats& stats() const;
  // Why the port is not open, empty while it is.
  const std::string& last_error() const;

 private:
  class Impl;
  std::shared_ptr<Impl> impl_;
};

}  // namespace fieldgate::modbus
