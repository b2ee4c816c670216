// Modbus PDU codec (Modbus Application Protocol V1.1b3): requests in, responses out, no I/O.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace fieldgate::modbus {

inline constexpr std::size_t max_pdu_size = 253;

enum class FunctionCode : std::uint8_t {
  read_coils = 0x01,
  read_discrete_inputs = 0x02,
  read_holding_registers = 0x03,
  read_input_registers = 0x04,
  write_single_coil = 0x05,
  write_single_register = 0x06,
  write_multiple_coils = 0x0F,
  write_multiple_registers = 0x10,
  read_write_multiple_registers = 0x17,
  encapsulated_interface = 0x2B,  // only MEI type 0x0E, read device identification
};

inline constexpr std::uint8_t mei_read_device_identification = 0x0E;

enum class ExceptionCode : std::uint8_t {
  illegal_function = 0x01,
  illegal_data_address = 0x02,
  illegal_data_value = 0x03,
  server_device_failure = 0x04,
  acknowledge = 0x05,
  server_busy = 0x06,
  gateway_path_unavailable = 0x0A,
  gateway_target_failed = 0x0B,
};

std::string_view to_string(ExceptionCode code);

enum class BitTable : std::uint8_t { coils, discrete_inputs };
enum class RegisterTable : std::uint8_t { holding_registers, input_registers };

// Quantity limits from the spec; each keeps a response or request within max_pdu_size.
inline constexpr std::uint16_t max_read_bits = 2000;
inline constexpr std::uint16_t max_read_registers = 125;
inline constexpr std::uint16_t max_write_coils = 1968;
inline constexpr std::uint16_t max_write_registers = 123;
inline constexpr std::uint16_t max_read_write_read_registers = 125;
inline constexpr std::uint16_t max_read_write_write_registers = 121;

struct ReadBitsRequest {  // 0x01, 0x02
  BitTable table;
  std::uint16_t address;
  std::uint16_t count;
  bool operator==(const ReadBitsRequest&) const = default;
};

struct ReadRegistersRequest {  // 0x03, 0x04
  RegisterTable table;
  std::uint16_t address;
  std::uint16_t count;
  bool operator==(const ReadRegistersRequest&) const = default;
};

struct WriteSingleCoilRequest {  // 0x05
  std::uint16_t address;
  bool value;
  bool operator==(const WriteSingleCoilRequest&) const = default;
};

struct WriteSingleRegisterRequest {  // 0x06
  std::uint16_t address;
  std::uint16_t value;
  bool operator==(const WriteSingleRegisterRequest&) const = default;
};

struct WriteCoilsRequest {  // 0x0F
  std::uint16_t address;
  std::vector<bool> values;
  bool operator==(const WriteCoilsRequest&) const = default;
};

struct WriteRegistersRequest {  // 0x10
  std::uint16_t address;
  std::vector<std::uint16_t> values;
  bool operator==(const WriteRegistersRequest&) const = default;
};

struct ReadWriteRegistersRequest {  // 0x17: the write is performed before the read
  std::uint16_t read_address;
  std::uint16_t read_count;
  std::uint16_t write_address;
  std::vector<std::uint16_t> values;
  bool operator==(const ReadWriteRegistersRequest&) const = default;
};

// 0x2B / 0x0E. Read device ID codes: 1 basic, 2 regular, 3 extended (streams starting at
// object_id), 4 one object.
struct ReadDeviceIdentificationRequest {
  std::uint8_t read_code;
  std::uint8_t object_id;
  bool operator==(const ReadDeviceIdentificationRequest&) const = default;
};

using Request = std::variant<ReadBitsRequest, ReadRegistersRequest, WriteSingleCoilRequest,
                             WriteSingleRegisterRequest, WriteCoilsRequest, WriteRegistersRequest,
                             ReadWriteRegistersRequest, ReadDeviceIdentificationRequest>;

FunctionCode function_code(const Request& request);
bool is_write(const Request& request);

// Checks follow the spec's state diagrams: unsupported function -> 0x01, malformed length,
// quantity or byte count -> 0x03, address + quantity past 0xFFFF -> 0x02.
// On an exception, the response is encode_exception(pdu[0], code).
std::variant<Request, ExceptionCode> parse_request(std::span<const std::uint8_t> pdu);

// Response encoders. Each returns a complete response PDU starting with the function code.
std::vector<std::uint8_t> encode_exception(std::uint8_t function, ExceptionCode code);
std::vector<std::uint8_t> encode_read_bits_response(BitTable table, const std::vector<bool>& bits);
// For 0x03, 0x04 and 0x17.
std::vector<std::uint8_t> encode_read_registers_response(FunctionCode function,
                                                         std::span<const std::uint16_t> values);
std::vector<std::uint8_t> encode_write_single_coil_response(std::uint16_t address, bool value);
std::vector<std::uint8_t> encode_write_single_register_response(std::uint16_t address,
                                                                std::uint16_t value);
// For 0x0F and 0x10.
std::vector<std::uint8_t> encode_write_multiple_response(FunctionCode function,
                                                         std::uint16_t address,
                                                         std::uint16_t count);

// Device identification objects: 0x00 VendorName, 0x01 ProductCode, 0x02 MajorMinorRevision
// (basic, mandatory), 0x03-0x06 VendorUrl, ProductName, ModelName, UserApplicationName
// (regular, optional).
struct DeviceIdObject {
  std::uint8_t id;
  std::string value;
};
using DeviceIdentification = std::vector<DeviceIdObject>;

// The 0x2B/0x0E response for `objects` (sorted by id, basic ones present): a stream answers
// the objects of the requested category from object_id on (from 0 if object_id is not one of
// them), as many as fit, with "more follows" and the next id otherwise; code 4 answers the
// one object, or exception 0x02 if there is none with that id. Values are cut to fit a PDU.
std::vector<std::uint8_t> encode_device_identification_response(
    const ReadDeviceIdentificationRequest& request, const DeviceIdentification& objects);

}  // namespace fieldgate::modbus
