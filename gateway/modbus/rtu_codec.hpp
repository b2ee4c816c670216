// Modbus RTU framing (Modbus over Serial Line V1.02 §2.5): the ADU is unit, PDU and CRC-16,
// and a frame ends where the line has been silent for 3.5 character times.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace fieldgate::modbus {

inline constexpr std::size_t rtu_min_adu_size = 4;    // unit, function code, CRC
inline constexpr std::size_t rtu_max_adu_size = 256;  // unit, 253-byte PDU, CRC
inline constexpr std::uint8_t rtu_broadcast_unit = 0;

// CRC-16/MODBUS: polynomial 0xA001 (reflected 0x8005), initial value 0xFFFF. Sent low byte
// first, the only little-endian field in Modbus.
std::uint16_t rtu_crc16(std::span<const std::uint8_t> bytes);

// Appends unit, pdu and the CRC to out.
void encode_rtu_adu(std::uint8_t unit, std::span<const std::uint8_t> pdu,
                    std::vector<std::uint8_t>& out);

enum class RtuFrameError {
  none,
  too_short,  // fewer than 4 bytes: no unit, function code and CRC
  too_long,   // more than 256 bytes: an overrun, or frames run together
  truncated,  // the CRC fails and the request's own length fields say bytes are missing
  bad_crc,    // the CRC fails otherwise (noise, or two frames without a silent gap)
};

std::string_view to_string(RtuFrameError error);

struct RtuFrame {
  std::uint8_t unit = 0;
  std::span<const std::uint8_t> pdu;  // points into the decoded bytes
};

struct RtuDecodeResult {
  RtuFrameError error = RtuFrameError::none;
  RtuFrame frame;
};

// Checks one frame as delimited by the silent interval: size and CRC. A frame with a good CRC
// is returned whatever its PDU holds; PDU checks are parse_request()'s.
RtuDecodeResult decode_rtu_adu(std::span<const std::uint8_t> adu);

// The size a request ADU starting with these bytes must have, from its function code and
// byte count; nullopt when the function code has no fixed request layout or the bytes that
// tell the size have not arrived.
std::optional<std::size_t> rtu_request_size(std::span<const std::uint8_t> adu_prefix);

// Whether these bytes are a request still missing bytes by its own length fields (fewer than
// two bytes, or fewer than rtu_request_size says) and do not already form a frame with a good
// CRC (another slave's short answer on a shared line is complete as it is).
bool rtu_request_incomplete(std::span<const std::uint8_t> bytes);

// Character time for bits_per_character bits (start, data, parity, stop) at baud.
std::chrono::nanoseconds rtu_character_time(unsigned baud, unsigned bits_per_character);
// The inter-frame silence t3.5: 3.5 character times up to 19200 baud, 1750 us above, as the
// spec fixes it there (§2.5.1.1) to spare receivers a timer per character.
std::chrono::microseconds rtu_silent_interval(unsigned baud, unsigned bits_per_character);

}  // namespace fieldgate::modbus
