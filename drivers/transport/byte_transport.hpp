#pragma once

#include <boost/asio/awaitable.hpp>
#include <boost/asio/buffer.hpp>

#include <chrono>
#include <cstddef>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>

namespace fieldgate {

namespace asio = boost::asio;

// What a read with a deadline brought: bytes, an error, or the deadline (bytes may still be
// on their way in the OS; Link looks before it calls it a timeout).
struct TransportRead {
  std::error_code error;
  std::size_t size = 0;
  bool timed_out = false;
};

// A byte stream to one field link: a serial port or a serial device server's TCP socket.
// Only the bus that owns it calls it, one operation at a time.
class ByteTransport {
 public:
  virtual ~ByteTransport() = default;
  virtual asio::awaitable<std::error_code> open() = 0;
  virtual void close() = 0;
  virtual bool is_open() const = 0;
  virtual asio::awaitable<std::error_code> write(std::string_view bytes) = 0;
  // Completes when at least one byte arrived; cancellable through the awaiting coroutine's
  // cancellation slot, so `read_some(...) || timer` works.
  virtual asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) = 0;
  // read_some, given up at `deadline`. This one races read_some against a timer (two
  // coroutines and a parallel group per read); the stream transports override it with their
  // own timer, as it is on every exchange's path.
  virtual asio::awaitable<TransportRead> read_some_until(
      asio::mutable_buffer buffer, std::chrono::steady_clock::time_point deadline);
  // Changes the line rate at once (a controller that switches rate mid-session); transports
  // without a rate refuse.
  virtual std::error_code set_baud(unsigned baud) {
    (void)baud;
    return std::make_error_code(std::errc::operation_not_supported);
  }
  virtual unsigned baud() const { return 0; }
  // Waits until everything written has left the UART (so a rate change cannot cut it).
  virtual void drain() {}
  // Reads what the OS has already buffered without waiting (0 if nothing). Link relies on it
  // to see strays before a request, so every transport must be able to tell.
  virtual std::size_t read_available(asio::mutable_buffer buffer) = 0;
  // Writes what the OS takes at once, without waiting; returns how many bytes it took (0 also
  // where the transport cannot write without waiting, the default: nothing is then sent ahead).
  virtual std::size_t write_available(std::string_view bytes) {
    (void)bytes;
    return 0;
  }
  // Drops whatever the OS has buffered but nobody read yet.
  virtual void discard_input() = 0;
  virtual std::string describe() const = 0;
  // Wire time of one character in microseconds (0 when unknown, e.g. TCP).
  virtual double char_time_us() const = 0;
};

}  // namespace fieldgate
