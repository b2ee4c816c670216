// CiA 301 frame codecs and tables, pure functions: data types and their byte encoding, SDO
// command bytes, abort code and emergency code texts, NMT, heartbeat and EMCY frames.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/canopen/canopen_time.hpp"
#include "drivers/transport/can_frame.hpp"

namespace fieldgate::canopen {

namespace cob {
constexpr uint32_t nmt = 0x000;
constexpr uint32_t emcy = 0x080;
constexpr uint32_t tpdo1 = 0x180;
constexpr uint32_t sdo_tx = 0x580;  // server to client (responses)
constexpr uint32_t sdo_rx = 0x600;  // client to server (requests)
constexpr uint32_t heartbeat = 0x700;
}  // namespace cob

constexpr int kMinNodeId = 1;
constexpr int kMaxNodeId = 127;

// CiA 301 static data types the gateway can put into registers, and the string types an action
// step may write or an upload may return.
enum class DataType {
  boolean,
  integer8,
  integer16,
  integer24,
  integer32,
  integer64,
  unsigned8,
  unsigned16,
  unsigned24,
  unsigned32,
  unsigned64,
  visible_string,
  octet_string,
};

// Names as CiA 301 and EDS files write them: BOOLEAN, INTEGER8 ... UNSIGNED64, VISIBLE_STRING,
// OCTET_STRING.
std::optional<DataType> parse_data_type(std::string_view name);
std::string_view to_string(DataType type);
std::string data_type_names();
bool is_integer(DataType type);
bool is_signed(DataType type);
std::size_t size_of(DataType type);  // bytes on the wire; 0 for strings
int64_t min_of(DataType type);
int64_t max_of(DataType type);  // UNSIGNED64 is limited to INT64_MAX inside the gateway
bool in_range(DataType type, int64_t value);

// Little-endian bytes of an integer of the type; the value must be in range.
std::vector<uint8_t> encode_integer(DataType type, int64_t value);
// Sign-extended value, or nullopt when fewer bytes than the type needs arrived.
std::optional<int64_t> decode_integer(DataType type, std::span<const uint8_t> bytes);

// --- SDO (CiA 301 7.2.4.3) ----------------------------------------------------------------

using SdoPayload = std::array<uint8_t, 8>;

namespace sdo_abort {
constexpr uint32_t toggle_bit = 0x05030000;
constexpr uint32_t timeout = 0x05040000;
constexpr uint32_t command_specifier = 0x05040001;
constexpr uint32_t out_of_memory = 0x05040005;
constexpr uint32_t unsupported_access = 0x06010000;
constexpr uint32_t write_only = 0x06010001;
constexpr uint32_t read_only = 0x06010002;
constexpr uint32_t no_object = 0x06020000;
constexpr uint32_t length_mismatch = 0x06070010;
constexpr uint32_t length_too_high = 0x06070012;
constexpr uint32_t length_too_low = 0x06070013;
constexpr uint32_t no_subindex = 0x06090011;
constexpr uint32_t value_range = 0x06090030;
constexpr uint32_t general = 0x08000000;
}  // namespace sdo_abort

// The CiA 301 meaning of an abort code ("object does not exist in the object dictionary");
// unknown codes get a generic text with their class.
std::string abort_text(uint32_t code);

SdoPayload sdo_upload_request(uint16_t index, uint8_t sub);
SdoPayload sdo_upload_segment_request(bool toggle);
// Expedited for 1..4 bytes, otherwise the initiate of a segmented download with the size.
SdoPayload sdo_download_request(uint16_t index, uint8_t sub, std::span<const uint8_t> data);
// Segment of up to 7 bytes; last marks the final segment.
SdoPayload sdo_download_segment(bool toggle, std::span<const uint8_t> data, bool last);
SdoPayload sdo_abort_request(uint16_t index, uint8_t sub, uint32_t code);
uint16_t sdo_index(const SdoPayload& p);
uint8_t sdo_subindex(const SdoPayload& p);
uint32_t sdo_u32(const SdoPayload& p);  // bytes 4..7, the size or abort code
CanFrame sdo_request_frame(uint8_t node, const SdoPayload& payload);

// --- NMT, heartbeat, EMCY ---------------------------------------------------------------

enum class NmtCommand : uint8_t {
  start = 0x01,
  stop = 0x02,
  enter_pre_operational = 0x80,
  reset_node = 0x81,
  reset_communication = 0x82,
};
std::string_view to_string(NmtCommand command);
// Node 0 addresses every node.
CanFrame nmt_frame(NmtCommand command, uint8_t node);

namespace nmt_state {
constexpr uint8_t boot_up = 0x00;
constexpr uint8_t stopped = 0x04;
constexpr uint8_t operational = 0x05;
constexpr uint8_t pre_operational = 0x7F;
}  // namespace nmt_state
std::string_view nmt_state_text(uint8_t state);

struct Heartbeat {
  uint8_t node = 0;
  uint8_t state = 0;    // with the node-guarding toggle bit removed
  bool toggle = false;  // bit 7: set in every other node-guarding reply, never in a heartbeat
};
std::optional<Heartbeat> parse_heartbeat(const CanFrame& frame);

struct Emergency {
  uint8_t node = 0;
  uint16_t code = 0;  // 0: error reset / no error
  uint8_t error_register = 0;
  std::array<uint8_t, 5> manufacturer{};
};
std::optional<Emergency> parse_emergency(const CanFrame& frame);
// The error code's class from CiA 301 table 21 ("current, device output side").
std::string emergency_text(uint16_t code);

// A CANopen node ID from a config address: 1..127, decimal or 0x hex.
std::optional<int> parse_node_id(std::string_view text, std::string& error);

}  // namespace fieldgate::canopen
