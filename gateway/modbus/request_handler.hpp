// What the Modbus server asks of whatever is behind it (the register map), and dispatch(),
// which ties the PDU codec to it.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <utility>  // Boost.Asio's awaitable headers rely on it being included first
#include <variant>
#include <vector>

#include <boost/asio/awaitable.hpp>

#include "gateway/modbus/pdu.hpp"

namespace fieldgate::modbus {

namespace asio = boost::asio;

// The values read, or the exception to answer with. Implicitly built from either:
//   return std::vector<std::uint16_t>{1, 2};   return ExceptionCode::illegal_data_address;
template <class Values>
class ReadResult {
 public:
  ReadResult(Values values) : result_(std::move(values)) {}
  ReadResult(ExceptionCode exception) : result_(exception) {}

  bool ok() const { return result_.index() == 0; }
  const Values& values() const { return std::get<0>(result_); }
  Values& values() { return std::get<0>(result_); }
  ExceptionCode exception() const { return std::get<1>(result_); }

 private:
  std::variant<Values, ExceptionCode> result_;
};

using ReadBitsResult = ReadResult<std::vector<bool>>;
using ReadRegistersResult = ReadResult<std::vector<std::uint16_t>>;
using DeviceIdentificationResult = ReadResult<DeviceIdentification>;

// Success (default), or the exception to answer with.
class WriteResult {
 public:
  WriteResult() = default;
  WriteResult(ExceptionCode exception) : exception_(exception) {}
  static WriteResult success() { return {}; }

  bool ok() const { return !exception_; }
  ExceptionCode exception() const { return *exception_; }

 private:
  std::optional<ExceptionCode> exception_;
};

class RequestHandler {
 public:
  virtual ~RequestHandler() = default;

  // Reads are called synchronously and must not block: they are served from the process image.
  // A result must hold exactly `count` values (anything else is answered with 0x04).
  virtual ReadBitsResult read_bits(std::uint8_t unit, BitTable table, std::uint16_t address,
                                   std::uint16_t count) = 0;
  virtual ReadRegistersResult read_registers(std::uint8_t unit, RegisterTable table,
                                             std::uint16_t address, std::uint16_t count) = 0;

  // Writes complete when the controller confirmed them; the Modbus reply waits for that.
  // Only holding registers and coils are writable in Modbus. `values` stays valid until the
  // returned awaitable completes.
  virtual asio::awaitable<WriteResult> write_registers(std::uint8_t unit, std::uint16_t address,
                                                       std::span<const std::uint16_t> values) = 0;
  virtual asio::awaitable<WriteResult> write_coils(std::uint8_t unit, std::uint16_t address,
                                                   std::vector<bool> values) = 0;

  // FC 0x2B/0x0E: the unit's identification objects, sorted by id, 0x00-0x02 at least. Called
  // synchronously like the reads. The default answers 0x01 (not supported).
  virtual DeviceIdentificationResult device_identification(std::uint8_t unit);
};

// Parses a request PDU, calls the handler and returns the response PDU (normal or exception).
// 0x05/0x06 go to write_coils/write_registers with one value; 0x17 writes, then reads the
// holding registers. A handler that throws is answered with 0x04. `request_pdu` must stay
// valid until the returned awaitable completes.
asio::awaitable<std::vector<std::uint8_t>> dispatch(RequestHandler& handler, std::uint8_t unit,
                                                    std::span<const std::uint8_t> request_pdu);

}  // namespace fieldgate::modbus
