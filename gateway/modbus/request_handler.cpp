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

asio::awaitable<Pdu> handle(RequestHandler& handler, std::uint8_t unit, const Request& request) {
  const FunctionCode function = function_code(request);
  const auto fc = static_cast<std::uint8_t>(function);

  if (const auto* r = std::get_if<ReadDeviceIdentificationRequest>(&request)) {
    DeviceIdentificationResult result = handler.device_identification(unit);
    if (!result.ok()) co_return encode_exception(fc, result.exception());
    co_return encode_device_identification_response(*r, result.values());
  }
  if (const auto* r = std::get_if<ReadBitsRequest>(&request)) {
    co_return read_bits(handler, unit, *r);
  }
  if (const auto* r = std::get_if<ReadRegistersRequest>(&request)) {
    co_return read_registers(handler, unit, function, r->table, r->address, r->count);
  }
  if (const auto* r = std::get_if<WriteSingleCoilRequest>(&request)) {
    const WriteResult result =
        co_await handler.write_coils(unit, r->address, std::vector<bool>(1, r->value));
    if (!result.ok()) co_return encode_exception(fc, result.exception());
    co_return encode_write_single_coil_response(r->address, r->value);
  }
  if (const auto* r = std::get_if<WriteSingleRegisterRequest>(&request)) {
    const std::uint16_t value = r->value;
    const WriteResult result = co_await handler.write_registers(
        unit, r->address, std::span<const std::uint16_t>(&value, 1));
    if (!result.ok()) co_return encode_exception(fc, result.exception());
    co_return encode_write_single_register_response(r->address, r->value);
  }
  if (const auto* r = std::get_if<WriteCoilsRequest>(&request)) {
    const WriteResult result = co_await handler.write_coils(unit, r->address, r->values);
    if (!result.ok()) co_return encode_exception(fc, result.exception());
    co_return encode_write_multiple_response(function, r->address,
                                             static_cast<std::uint16_t>(r->values.size()));
  }
  if (const auto* r = std::get_if<WriteRegistersRequest>(&request)) {
    const WriteResult result = co_await handler.write_registers(unit, r->address, r->values);
    if (!result.ok()) co_return encode_exception(fc, result.exception());
    co_return encode_write_multiple_response(function, r->address,
                                             static_cast<std::uint16_t>(r->values.size()));
  }
  const auto& r = std::get<ReadWriteRegistersRequest>(request);
  const WriteResult result = co_await handler.write_registers(unit, r.write_address, r.values);
  if (!result.ok()) co_return encode_exception(fc, result.exception());
  co_return read_registers(handler, unit, function, RegisterTable::holding_registers,
                           r.read_address, r.read_count);
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
