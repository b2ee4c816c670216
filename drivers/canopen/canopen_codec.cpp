#include "drivers/canopen/canopen_codec.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>

#include "mapping/yaml_reader.hpp"

namespace fieldgate::canopen {

namespace {

struct DataTypeInfo {
  DataType type;
  std::string_view name;
  std::size_t size;
  bool is_signed;
};

constexpr DataTypeInfo kDataTypes[] = {
    {DataType::boolean, "BOOLEAN", 1, false},
    {DataType::integer8, "INTEGER8", 1, true},
    {DataType::integer16, "INTEGER16", 2, true},
    {DataType::integer24, "INTEGER24", 3, true},
    {DataType::integer32, "INTEGER32", 4, true},
    {DataType::integer64, "INTEGER64", 8, true},
    {DataType::unsigned8, "UNSIGNED8", 1, false},
    {DataType::unsigned16, "UNSIGNED16", 2, false},
    {DataType::unsigned24, "UNSIGNED24", 3, false},
    {DataType::unsigned32, "UNSIGNED32", 4, false},
    {DataType::unsigned64, "UNSIGNED64", 8, false},
    {DataType::visible_string, "VISIBLE_STRING", 0, false},
    {DataType::octet_string, "OCTET_STRING", 0, false},
};

const DataTypeInfo& info(DataType type) {
  for (const auto& i : kDataTypes)
    if (i.type == type) return i;
  return kDataTypes[0];
}

// CiA 301 table 22.
struct AbortEntry {
  uint32_t code;
  const char* text;
};
constexpr AbortEntry kAbortCodes[] = {
    {0x05030000, "toggle bit not alternated"},
    {0x05040000, "SDO protocol timed out"},
    {0x05040001, "client/server command specifier not valid or unknown"},
    {0x05040002, "invalid block size"},
    {0x05040003, "invalid sequence number"},
    {0x05040004, "CRC error"},
    {0x05040005, "out of memory"},
    {0x06010000, "unsupported access to an object"},
    {0x06010001, "attempt to read a write only object"},
    {0x06010002, "attempt to write a read only object"},
    {0x06020000, "object does not exist in the object dictionary"},
    {0x06040041, "object cannot be mapped to the PDO"},
    {0x06040042, "the number and length of the objects to be mapped would exceed PDO length"},
    {0x06040043, "general parameter incompatibility reason"},
    {0x06040047, "general internal incompatibility in the device"},
    {0x06060000, "access failed due to a hardware error"},
    {0x06070010, "data type does not match, length of service parameter does not match"},
    {0x06070012, "data type does not match, length of service parameter too high"},
    {0x06070013, "data type does not match, length of service parameter too low"},
    {0x06090011, "sub-index does not exist"},
    {0x06090030, "invalid value for parameter (download only)"},
    {0x06090031, "value of parameter written too high (download only)"},
    {0x06090032, "value of parameter written too low (download only)"},
    {0x06090036, "maximum value is less than minimum value"},
    {0x060A0023, "resource not available: SDO connection"},
    {0x08000000, "general error"},
    {0x08000020, "data cannot be transferred or stored to the application"},
    {0x08000021,
     "data cannot be transferred or stored to the application because of local control"},
    {0x08000022,
     "data cannot be transferred or stored to the application because of the present device "
     "state"},
    {0x08000023, "object dictionary dynamic generation fails or no object dictionary is present"},
    {0x08000024, "no data available"},
};

// CiA 301 table 21, most specific first.
struct EmcyClass {
  uint16_t code;
  uint16_t mask;
  const char* text;
};
constexpr EmcyClass kEmcyClasses[] = {
    {0x0000, 0xFF00, "error reset or no error"},
    {0x1000, 0xFF00, "generic error"},
    {0x2100, 0xFF00, "current, device input side"},
    {0x2200, 0xFF00, "current inside the device"},
    {0x2300, 0xFF00, "current, device output side"},
    {0x2000, 0xF000, "current"},
    {0x3100, 0xFF00, "mains voltage"},
    {0x3200, 0xFF00, "voltage inside the device"},
    {0x3300, 0xFF00, "output voltage"},
    {0x3000, 0xF000, "voltage"},
    {0x4100, 0xFF00, "ambient temperature"},
    {0x4200, 0xFF00, "device temperature"},
    {0x4000, 0xF000, "temperature"},
    {0x5000, 0xF000, "device hardware"},
    {0x6100, 0xFF00, "internal software"},
    {0x6200, 0xFF00, "user software"},
    {0x6300, 0xFF00, "data set"},
    {0x6000, 0xF000, "device software"},
    {0x7000, 0xF000, "additional modules"},
    {0x8110, 0xFFFF, "CAN overrun (objects lost)"},
    {0x8120, 0xFFFF, "CAN in error passive mode"},
    {0x8130, 0xFFFF, "life guard error or heartbeat error"},
    {0x8140, 0xFFFF, "recovered from bus off"},
    {0x8150, 0xFFFF, "CAN-ID collision"},
    {0x8100, 0xFF00, "communication"},
    {0x8210, 0xFFFF, "PDO not processed due to length error"},
    {0x8220, 0xFFFF, "PDO length exceeded"},
    {0x8230, 0xFFFF, "DAM MPDO not processed, destination object not available"},
    {0x8240, 0xFFFF, "unexpected SYNC data length"},
    {0x8250, 0xFFFF, "RPDO timeout"},
    {0x8200, 0xFF00, "protocol error"},
    {0x8000, 0xF000, "monitoring"},
    {0x9000, 0xFF00, "external error"},
    {0xF000, 0xFF00, "additional functions"},
    {0xFF00, 0xFF00, "device specific"},
};

void put_mux(SdoPayload& p, uint16_t index, uint8_t sub) {
  p[1] = static_cast<uint8_t>(index);
  p[2] = static_cast<uint8_t>(index >> 8);
  p[3] = sub;
}

void put_u32(SdoPayload& p, uint32_t v) {
  for (int i = 0; i < 4; ++i)
    p[static_cast<std::size_t>(4 + i)] = static_cast<uint8_t>(v >> (8 * i));
}

}  // namespace

std::optional<DataType> parse_data_type(std::string_view name) {
  for (const auto& i : kDataTypes)
    if (i.name == name) return i.type;
  return std::nullopt;
}

std::string_view to_string(DataType type) {
  return info(type).name;
}

std::string data_type_names() {
  std::string names;
  for (const auto& i : kDataTypes) names += (names.empty() ? "" : ", ") + std::string(i.name);
  return names;
}

bool is_integer(DataType type) {
  return info(type).size > 0;
}

bool is_signed(DataType type) {
  return info(type).is_signed;
}

std::size_t size_of(DataType type) {
  return info(type).size;
}

int64_t min_of(DataType type) {
  const auto& i = info(type);
  if (!i.is_signed || i.size == 0) return 0;
  if (i.size == 8) return std::numeric_limits<int64_t>::min();
  return -(int64_t{1} << (8 * i.size - 1));
}

int64_t max_of(DataType type) {
  const auto& i = info(type);
  if (type == DataType::boolean) return 1;
  if (i.size == 0) return 0;
  if (i.size == 8) return std::numeric_limits<int64_t>::max();
  return i.is_signed ? (int64_t{1} << (8 * i.size - 1)) - 1 : (int64_t{1} << (8 * i.size)) - 1;
}

bool in_range(DataType type, int64_t value) {
  return is_integer(type) && value >= min_of(type) && value <= max_of(type);
}

std::vector<uint8_t> encode_integer(DataType type, int64_t value) {
  const std::size_t n = size_of(type);
  std::vector<uint8_t> out(n);
  const auto u = static_cast<uint64_t>(value);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<uint8_t>(u >> (8 * i));
  return out;
}

std::optional<int64_t> decode_integer(DataType type, std::span<const uint8_t> bytes) {
  const std::size_t n = size_of(type);
  if (n == 0 || bytes.size() < n) return std::nullopt;
  uint64_t u = 0;
  for (std::size_t i = 0; i < n; ++i) u |= static_cast<uint64_t>(bytes[i]) << (8 * i);
  if (is_signed(type) && n < 8 && (u >> (8 * n - 1)) & 1) u |= ~uint64_t{0} << (8 * n);
  if (type == DataType::boolean) u = u != 0 ? 1 : 0;
  return static_cast<int64_t>(u);
}

std::string abort_text(uint32_t code) {
  for (const auto& a : kAbortCodes)
    if (a.code == code) return a.text;
  switch (code >> 24) {
    case 0x05:
      return fmt::format("SDO protocol error 0x{:08X}", code);
    case 0x06:
      return fmt::format("access or parameter error 0x{:08X}", code);
    case 0x08:
      return fmt::format("general device error 0x{:08X}", code);
    default:
      return fmt::format("abort code 0x{:08X}", code);
  }
}

SdoPayload sdo_upload_request(uint16_t index, uint8_t sub) {
  SdoPayload p{};
  p[0] = 0x40;  // ccs 2: initiate upload
  put_mux(p, index, sub);
  return p;
}

SdoPayload sdo_upload_segment_request(bool toggle) {
  SdoPayload p{};
  p[0] = static_cast<uint8_t>(0x60 | (toggle ? 0x10 : 0));  // ccs 3
  return p;
}

SdoPayload sdo_download_request(uint16_t index, uint8_t sub, std::span<const uint8_t> data) {
  SdoPayload p{};
  put_mux(p, index, sub);
  if (!data.empty() && data.size() <= 4) {
    // ccs 1, n = 4 - size, e = 1, s = 1
    p[0] = static_cast<uint8_t>(0x20 | ((4 - data.size()) << 2) | 0x03);
    std::copy(data.begin(), data.end(), p.begin() + 4);
  } else {
    p[0] = 0x21;  // ccs 1, e = 0, s = 1: size in bytes 4..7
    put_u32(p, static_cast<uint32_t>(data.size()));
  }
  return p;
}

SdoPayload sdo_download_segment(bool toggle, std::span<const uint8_t> data, bool last) {
  SdoPayload p{};
  // ccs 0, t, n = 7 - size, c
  p[0] = static_cast<uint8_t>((toggle ? 0x10 : 0) | ((7 - data.size()) << 1) | (last ? 1 : 0));
  std::copy(data.begin(), data.end(), p.begin() + 1);
  return p;
}

SdoPayload sdo_abort_request(uint16_t index, uint8_t sub, uint32_t code) {
  SdoPayload p{};
  p[0] = 0x80;
  put_mux(p, index, sub);
  put_u32(p, code);
  return p;
}

uint16_t sdo_index(const SdoPayload& p) {
  return static_cast<uint16_t>(p[1] | (p[2] << 8));
}

uint8_t sdo_subindex(const SdoPayload& p) {
  return p[3];
}

uint32_t sdo_u32(const SdoPayload& p) {
  return static_cast<uint32_t>(p[4]) | static_cast<uint32_t>(p[5]) << 8 |
         static_cast<uint32_t>(p[6]) << 16 | static_cast<uint32_t>(p[7]) << 24;
}

CanFrame sdo_request_frame(uint8_t node, const SdoPayload& payload) {
  CanFrame f;
  f.id = cob::sdo_rx + node;
  f.len = 8;
  f.data = payload;
  return f;
}

std::string_view to_string(NmtCommand command) {
  switch (command) {
    case NmtCommand::start:
      return "start";
    case NmtCommand::stop:
      return "stop";
    case NmtCommand::enter_pre_operational:
      return "pre-operational";
    case NmtCommand::reset_node:
      return "reset";
    case NmtCommand::reset_communication:
      return "reset-communication";
  }
  return "?";
}

CanFrame nmt_frame(NmtCommand command, uint8_t node) {
  return CanFrame::make(cob::nmt, {static_cast<uint8_t>(command), node});
}

std::string_view nmt_state_text(uint8_t state) {
  switch (state) {
    case nmt_state::boot_up:
      return "boot-up";
    case nmt_state::stopped:
      return "stopped";
    case nmt_state::operational:
      return "operational";
    case nmt_state::pre_operational:
      return "pre-operational";
    default:
      return "unknown state";
  }
}

std::optional<Heartbeat> parse_heartbeat(const CanFrame& frame) {
  if (frame.error || frame.rtr || frame.len < 1) return std::nullopt;
  if (frame.id <= cob::heartbeat || frame.id > cob::heartbeat + kMaxNodeId) return std::nullopt;
  return Heartbeat{static_cast<uint8_t>(frame.id - cob::heartbeat),
                   static_cast<uint8_t>(frame.data[0] & 0x7F), (frame.data[0] & 0x80) != 0};
}

std::optional<Emergency> parse_emergency(const CanFrame& frame) {
  if (frame.error || frame.rtr) return std::nullopt;
  if (frame.id <= cob::emcy || frame.id > cob::emcy + kMaxNodeId) return std::nullopt;
  // CiA 301 requires 8 bytes; devices that send fewer still say something useful.
  if (frame.len < 3) return std::nullopt;
  Emergency e;
  e.node = static_cast<uint8_t>(frame.id - cob::emcy);
  e.code = static_cast<uint16_t>(frame.data[0] | (frame.data[1] << 8));
  e.error_register = frame.data[2];
  std::copy(frame.data.begin() + 3, frame.data.end(), e.manufacturer.begin());
  return e;
}

std::string emergency_text(uint16_t code) {
  for (const auto& c : kEmcyClasses)
    if ((code & c.mask) == c.code) return c.text;
  return "reserved error code";
}

std::optional<int> parse_node_id(std::string_view text, std::string& error) {
  const auto v = parse_integer_text(text);
  if (!v || *v < kMinNodeId || *v > kMaxNodeId) {
    error = fmt::format("expected a CANopen node ID 1..127, found '{}'", text);
    return std::nullopt;
  }
  return static_cast<int>(*v);
}

}  // namespace fieldgate::canopen
