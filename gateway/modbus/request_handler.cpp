#include "gateway/modbus/request_handler.hpp"

namespace fieldgate::modbus {
namespace {

using Pdu = std::vector<std::uint8_t>;

Pdu read_bits(RequestHandler& handler, std::uint8_t unit, const ReadBitsRequest& r) {
  const std::uint8_t function = r.table == BitTable::coils ? 0x01 : 0x02;
  ReadBitsResult result = handler.read_bits(unit, r.table, r.address, r.count);
  if (!result.ok()) return encode_exception(function, result.exception());
  if (result.values().size() != r.count) {
    return encode_exception(function, ExceptionCode::server_device_failure);
  }
  return encode_read_bits_response(r.table, result.values());
}

Pdu read_registers(RequestHandler& handler, std::uint8_t unit, FunctionCode function,
                   RegisterTable table, std::uint16_t address, std::uint16_t count) {
  ReadRegistersResult result = handler.read_registers(unit, table, address, count);
  if (!result.ok())
    return encode_exception(static_cast<std::uint8_t>(function), result.exception());
  if (result.values().size() != count) {
    return encode_exception(static_cast<std::uint8_t>(function),
                            ExceptionCode::server_device_failure);
  }
  return encode_read_registers_response(function, result.values());
}

// One overload per request type: std::visit makes a request type without one a compile error.
asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, FunctionCode function,
                            const ReadDeviceIdentificationRequest& r) {
  DeviceIdentificationResult result = handler.device_identification(unit);
  if (!result.ok())
    co_return encode_exception(static_cast<std::uint8_t>(function), result.exception());
  co_return encode_device_identification_response(r, result.values());
}

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, FunctionCode,
                            const ReadBitsRequest& r) {
  co_return read_bits(handler, unit, r);
}

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, FunctionCode function,
                            const ReadRegistersRequest& r) {
  co_return read_registers(handler, unit, function, r.table, r.address, r.count);
}

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, FunctionCode function,
                            const WriteSingleCoilRequest& r) {
  const WriteResult result =
      co_await handler.write_coils(unit, r.address, std::vector<bool>(1, r.value));
  if (!result.ok())
    co_return encode_exception(static_cast<std::uint8_t>(function), result.exception());
  co_return encode_write_single_coil_response(r.address, r.value);
}

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, FunctionCode function,
                            const WriteSingleRegisterRequest& r) {
  const std::uint16_t value = r.value;
  const WriteResult result =
      co_await handler.write_registers(unit, r.address, std::span<const std::uint16_t>(&value, 1));
  if (!result.ok())
    co_return encode_exception(static_cast<std::uint8_t>(function), result.exception());
  co_return encode_write_single_register_response(r.address, r.value);
}

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, FunctionCode function,
                            const WriteCoilsRequest& r) {
  const WriteResult result = co_await handler.write_coils(unit, r.address, r.values);
  if (!result.ok())
    co_return encode_exception(static_cast<std::uint8_t>(function), result.exception());
  co_return encode_write_multiple_response(function, r.address,
                                           static_cast<std::uint16_t>(r.values.size()));
}

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, FunctionCode function,
                            const WriteRegistersRequest& r) {
  const WriteResult result = co_await handler.write_registers(unit, r.address, r.values);
  if (!result.ok())
    co_return encode_exception(static_cast<std::uint8_t>(function), result.exception());
  co_return encode_write_multiple_response(function, r.address,
                                           static_cast<std::uint16_t>(r.values.size()));
}

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, FunctionCode function,
                            const ReadWriteRegistersRequest& r) {
  const WriteResult result = co_await handler.write_registers(unit, r.write_address, r.values);
  if (!result.ok())
    co_return encode_exception(static_cast<std::uint8_t>(function), result.exception());
  co_return read_registers(handler, unit, function, RegisterTable::holding_registers,
                           r.read_address, r.read_count);
}

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, const Request& request) {
  const FunctionCode function = function_code(request);
  const auto one = [&handler, unit, function](const auto& r) {
    return handle(handler, unit, function, r);
  };
  auto pending = std::visit(one, request);
  co_return co_await std::move(pending);
}

}  // namespace

DeviceIdentificationResult RequestHandler::device_identification(std::uint8_t) {
  return ExceptionCode::illegal_function;
}

asio::awaitable<std::vector<std::uint8_t>> dispatch(RequestHandler& handler, std::uint8_t unit,
                                                    std::span<const std::uint8_t> request_pdu) {
  const std::uint8_t function = request_pdu.empty() ? 0 : request_pdu[0];
  auto parsed = parse_request(request_pdu);
  if (const auto* exception = std::get_if<ExceptionCode>(&parsed)) {
    co_return encode_exception(function, *exception);
  }
  try {
    co_return co_await handle(handler, unit, std::get<Request>(parsed));
  } catch (...) {
  }
  co_return encode_exception(function, ExceptionCode::server_device_failure);
}

}  // namespace fieldgate::modbus
