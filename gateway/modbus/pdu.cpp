#include "gateway/modbus/pdu.hpp"

#include <algorithm>

namespace fieldgate::modbus {
namespace {

std::uint16_t get16(std::span<const std::uint8_t> pdu, std::size_t offset) {
  return static_cast<std::uint16_t>((pdu[offset] << 8) | pdu[offset + 1]);
}

void put16(std::vector<std::uint8_t>& out, std::uint16_t value) {
  out.push_back(static_cast<std::uint8_t>(value >> 8));
  out.push_back(static_cast<std::uint8_t>(value & 0xFF));
}

bool past_end(std::uint16_t address, std::uint16_t count) {
  return std::uint32_t{address} + count > 0x10000;
}

std::vector<bool> unpack_bits(std::span<const std::uint8_t> bytes, std::uint16_t count) {
  std::vector<bool> bits(count);
  for (std::size_t i = 0; i < count; ++i) bits[i] = (bytes[i / 8] >> (i % 8)) & 1;
  return bits;
}

std::vector<std::uint16_t> unpack_registers(std::span<const std::uint8_t> bytes,
                                            std::uint16_t count) {
  std::vector<std::uint16_t> values(count);
  for (std::size_t i = 0; i < count; ++i) values[i] = get16(bytes, 2 * i);
  return values;
}

// 0x01-0x04: address, quantity.
std::variant<Request, ExceptionCode> parse_read(std::span<const std::uint8_t> pdu,
                                                std::uint16_t max_count, auto make) {
  if (pdu.size() != 5) return ExceptionCode::illegal_data_value;
  const std::uint16_t address = get16(pdu, 1);
  const std::uint16_t count = get16(pdu, 3);
  if (count < 1 || count > max_count) return ExceptionCode::illegal_data_value;
  if (past_end(address, count)) return ExceptionCode::illegal_data_address;
  return Request{make(address, count)};
}

std::variant<Request, ExceptionCode> parse_write_coils(std::span<const std::uint8_t> pdu) {
  if (pdu.size() < 6) return ExceptionCode::illegal_data_value;
  const std::uint16_t address = get16(pdu, 1);
  const std::uint16_t count = get16(pdu, 3);
  const std::size_t byte_count = pdu[5];
  if (count < 1 || count > max_write_coils || byte_count != (count + 7u) / 8 ||
      pdu.size() != 6 + byte_count) {
    return ExceptionCode::illegal_data_value;
  }
  if (past_end(address, count)) return ExceptionCode::illegal_data_address;
  return Request{WriteCoilsRequest{address, unpack_bits(pdu.subspan(6), count)}};
}

std::variant<Request, ExceptionCode> parse_write_registers(std::span<const std::uint8_t> pdu) {
  if (pdu.size() < 6) return ExceptionCode::illegal_data_value;
  const std::uint16_t address = get16(pdu, 1);
  const std::uint16_t count = get16(pdu, 3);
  const std::size_t byte_count = pdu[5];
  if (count < 1 || count > max_write_registers || byte_count != 2u * count ||
      pdu.size() != 6 + byte_count) {
    return ExceptionCode::illegal_data_value;
  }
  if (past_end(address, count)) return ExceptionCode::illegal_data_address;
  return Request{WriteRegistersRequest{address, unpack_registers(pdu.subspan(6), count)}};
}

std::variant<Request, ExceptionCode> parse_read_write(std::span<const std::uint8_t> pdu) {
  if (pdu.size() < 10) return ExceptionCode::illegal_data_value;
  const std::uint16_t read_address = get16(pdu, 1);
  const std::uint16_t read_count = get16(pdu, 3);
  const std::uint16_t write_address = get16(pdu, 5);
  const std::uint16_t write_count = get16(pdu, 7);
  const std::size_t byte_count = pdu[9];
  if (read_count < 1 || read_count > max_read_write_read_registers || write_count < 1 ||
      write_count > max_read_write_write_registers || byte_count != 2u * write_count ||
      pdu.size() != 10 + byte_count) {
    return ExceptionCode::illegal_data_value;
  }
  if (past_end(read_address, read_count) || past_end(write_address, write_count)) {
    return ExceptionCode::illegal_data_address;
  }
  return Request{ReadWriteRegistersRequest{read_address, read_count, write_address,
                                           unpack_registers(pdu.subspan(10), write_count)}};
}

}  // namespace

std::string_view to_string(ExceptionCode code) {
  switch (code) {
    case ExceptionCode::illegal_function:
      return "illegal function";
    case ExceptionCode::illegal_data_address:
      return "illegal data address";
    case ExceptionCode::illegal_data_value:
      return "illegal data value";
    case ExceptionCode::server_device_failure:
      return "server device failure";
    case ExceptionCode::acknowledge:
      return "acknowledge";
    case ExceptionCode::server_busy:
      return "server busy";
    case ExceptionCode::gateway_path_unavailable:
      return "gateway path unavailable";
    case ExceptionCode::gateway_target_failed:
      return "gateway target device failed to respond";
  }
  return "unknown exception";
}

FunctionCode function_code(const Request& request) {
  struct Visitor {
    FunctionCode operator()(const ReadBitsRequest& r) const {
      return r.table == BitTable::coils ? FunctionCode::read_coils
                                        : FunctionCode::read_discrete_inputs;
    }
    FunctionCode operator()(const ReadRegistersRequest& r) const {
      return r.table == RegisterTable::holding_registers ? FunctionCode::read_holding_registers
                                                         : FunctionCode::read_input_registers;
    }
    FunctionCode operator()(const WriteSingleCoilRequest&) const {
      return FunctionCode::write_single_coil;
    }
    FunctionCode operator()(const WriteSingleRegisterRequest&) const {
      return FunctionCode::write_single_register;
    }
    FunctionCode operator()(const WriteCoilsRequest&) const {
      return FunctionCode::write_multiple_coils;
    }
    FunctionCode operator()(const WriteRegistersRequest&) const {
      return FunctionCode::write_multiple_registers;
    }
    FunctionCode operator()(const ReadWriteRegistersRequest&) const {
      return FunctionCode::read_write_multiple_registers;
    }
    FunctionCode operator()(const ReadDeviceIdentificationRequest&) const {
      return FunctionCode::encapsulated_interface;
    }
  };
  return std::visit(Visitor{}, request);
}

bool is_write(const Request& request) {
  return !std::holds_alternative<ReadBitsRequest>(request) &&
         !std::holds_alternative<ReadRegistersRequest>(request) &&
         !std::holds_alternative<ReadDeviceIdentificationRequest>(request);
}

std::variant<Request, ExceptionCode> parse_request(std::span<const std::uint8_t> pdu) {
  if (pdu.empty()) return ExceptionCode::illegal_function;
  switch (static_cast<FunctionCode>(pdu[0])) {
    case FunctionCode::read_coils:
    case FunctionCode::read_discrete_inputs: {
      const BitTable table = pdu[0] == 0x01 ? BitTable::coils : BitTable::discrete_inputs;
      return parse_read(pdu, max_read_bits, [table](std::uint16_t address, std::uint16_t count) {
        return ReadBitsRequest{table, address, count};
      });
    }
    case FunctionCode::read_holding_registers:
    case FunctionCode::read_input_registers: {
      const RegisterTable table =
          pdu[0] == 0x03 ? RegisterTable::holding_registers : RegisterTable::input_registers;
      return parse_read(pdu, max_read_registers,
                        [table](std::uint16_t address, std::uint16_t count) {
                          return ReadRegistersRequest{table, address, count};
                        });
    }
    case FunctionCode::write_single_coil: {
      if (pdu.size() != 5) return ExceptionCode::illegal_data_value;
      const std::uint16_t value = get16(pdu, 3);
      if (value != 0xFF00 && value != 0x0000) return ExceptionCode::illegal_data_value;
      return Request{WriteSingleCoilRequest{get16(pdu, 1), value == 0xFF00}};
    }
    case FunctionCode::write_single_register:
      if (pdu.size() != 5) return ExceptionCode::illegal_data_value;
      return Request{WriteSingleRegisterRequest{get16(pdu, 1), get16(pdu, 3)}};
    case FunctionCode::write_multiple_coils:
      return parse_write_coils(pdu);
    case FunctionCode::write_multiple_registers:
      return parse_write_registers(pdu);
    case FunctionCode::read_write_multiple_registers:
      return parse_read_write(pdu);
    case FunctionCode::encapsulated_interface:
      // Other MEI types (0x0D CANopen general reference) are not served.
      if (pdu.size() < 2 || pdu[1] != mei_read_device_identification)
        return ExceptionCode::illegal_function;
      if (pdu.size() != 4 || pdu[2] < 1 || pdu[2] > 4) return ExceptionCode::illegal_data_value;
      return Request{ReadDeviceIdentificationRequest{pdu[2], pdu[3]}};
  }
  return ExceptionCode::illegal_function;
}

std::vector<std::uint8_t> encode_exception(std::uint8_t function, ExceptionCode code) {
  return {static_cast<std::uint8_t>(function | 0x80), static_cast<std::uint8_t>(code)};
}

std::vector<std::uint8_t> encode_read_bits_response(BitTable table, const std::vector<bool>& bits) {
  const std::size_t byte_count = (bits.size() + 7) / 8;
  std::vector<std::uint8_t> out(2 + byte_count, 0);
  out[0] = static_cast<std::uint8_t>(table == BitTable::coils ? FunctionCode::read_coils
                                                              : FunctionCode::read_discrete_inputs);
  out[1] = static_cast<std::uint8_t>(byte_count);
  for (std::size_t i = 0; i < bits.size(); ++i) {
    if (bits[i]) out[2 + i / 8] |= static_cast<std::uint8_t>(1u << (i % 8));
  }
  return out;
}

std::vector<std::uint8_t> encode_read_registers_response(FunctionCode function,
                                                         std::span<const std::uint16_t> values) {
  std::vector<std::uint8_t> out;
  out.reserve(2 + 2 * values.size());
  out.push_back(static_cast<std::uint8_t>(function));
  out.push_back(static_cast<std::uint8_t>(2 * values.size()));
  for (std::uint16_t v : values) put16(out, v);
  return out;
}

std::vector<std::uint8_t> encode_write_single_coil_response(std::uint16_t address, bool value) {
  std::vector<std::uint8_t> out{static_cast<std::uint8_t>(FunctionCode::write_single_coil)};
  put16(out, address);
  put16(out, value ? 0xFF00 : 0x0000);
  return out;
}

std::vector<std::uint8_t> encode_write_single_register_response(std::uint16_t address,
                                                                std::uint16_t value) {
  std::vector<std::uint8_t> out{static_cast<std::uint8_t>(FunctionCode::write_single_register)};
  put16(out, address);
  put16(out, value);
  return out;
}

std::vector<std::uint8_t> encode_write_multiple_response(FunctionCode function,
                                                         std::uint16_t address,
                                                         std::uint16_t count) {
  std::vector<std::uint8_t> out{static_cast<std::uint8_t>(function)};
  put16(out, address);
  put16(out, count);
  return out;
}

namespace {

// The highest object id of each read device ID code's category.
std::uint8_t last_id_of(std::uint8_t read_code) {
  return read_code == 1 ? 0x02 : read_code == 2 ? 0x7F : 0xFF;
}

}  // namespace

std::vector<std::uint8_t> encode_device_identification_response(
    const ReadDeviceIdentificationRequest& request, const DeviceIdentification& objects) {
  static constexpr std::size_t header = 7;  // 2B 0E code conformity more next count
  static constexpr std::size_t max_value = max_pdu_size - header - 2;
  bool regular = false;
  for (const auto& o : objects) regular = regular || (o.id > 0x02 && o.id <= 0x7F);
  // Stream and individual access, basic or regular category.
  const std::uint8_t conformity = regular ? 0x82 : 0x81;
  std::vector<std::uint8_t> out{static_cast<std::uint8_t>(FunctionCode::encapsulated_interface),
                                mei_read_device_identification,
                                request.read_code,
                                conformity,
                                0x00,
                                0x00,
                                0x00};
  const auto append = [&out](const DeviceIdObject& o) {
    const std::size_t n = std::min(o.value.size(), max_value);
    out.push_back(o.id);
    out.push_back(static_cast<std::uint8_t>(n));
    out.insert(out.end(), o.value.begin(), o.value.begin() + static_cast<std::ptrdiff_t>(n));
  };
  if (request.read_code == 4) {
    for (const auto& o : objects) {
      if (o.id != request.object_id) continue;
      append(o);
      out[6] = 1;
      return out;
    }
    return encode_exception(out[0], ExceptionCode::illegal_data_address);
  }
  const std::uint8_t last = last_id_of(request.read_code);
  bool known = false;
  for (const auto& o : objects) known = known || (o.id == request.object_id && o.id <= last);
  const std::uint8_t first = known ? request.object_id : 0x00;
  std::uint8_t count = 0;
  for (const auto& o : objects) {
    if (o.id < first || o.id > last) continue;
    if (out.size() + 2 + std::min(o.value.size(), max_value) > max_pdu_size) {
      out[4] = 0xFF;  // more follows
      out[5] = o.id;  // ask again from here
      break;
    }
    append(o);
    ++count;
  }
  out[6] = count;
  return out;
}

}  // namespace fieldgate::modbus
