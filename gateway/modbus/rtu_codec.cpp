#include "gateway/modbus/rtu_codec.hpp"

namespace fieldgate::modbus {

std::uint16_t rtu_crc16(std::span<const std::uint8_t> bytes) {
  std::uint16_t crc = 0xFFFF;
  for (const std::uint8_t b : bytes) {
    crc ^= b;
    for (int bit = 0; bit < 8; ++bit)
      crc = (crc & 1) ? static_cast<std::uint16_t>((crc >> 1) ^ 0xA001)
                      : static_cast<std::uint16_t>(crc >> 1);
  }
  return crc;
}

void encode_rtu_adu(std::uint8_t unit, std::span<const std::uint8_t> pdu,
                    std::vector<std::uint8_t>& out) {
  const std::size_t start = out.size();
  out.push_back(unit);
  out.insert(out.end(), pdu.begin(), pdu.end());
  const std::uint16_t crc = rtu_crc16(std::span<const std::uint8_t>(out).subspan(start));
  out.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  out.push_back(static_cast<std::uint8_t>(crc >> 8));
}

std::string_view to_string(RtuFrameError error) {
  switch (error) {
    case RtuFrameError::none:
      return "none";
    case RtuFrameError::too_short:
      return "too short";
    case RtuFrameError::too_long:
      return "too long";
    case RtuFrameError::truncated:
      return "truncated";
    case RtuFrameError::bad_crc:
      return "bad CRC";
  }
  return "?";
}

std::optional<std::size_t> rtu_request_size(std::span<const std::uint8_t> adu) {
  if (adu.size() < 2) return std::nullopt;
  // Sizes below count unit and CRC (3 bytes) around the request PDU.
  switch (adu[1]) {
    case 0x01:
    case 0x02:
    case 0x03:
    case 0x04:
    case 0x05:
    case 0x06:
      return 8;
    case 0x07:  // read exception status
    case 0x0B:  // get comm event counter
    case 0x0C:  // get comm event log
    case 0x11:  // report server ID
      return 4;
    case 0x0F:
    case 0x10:
      if (adu.size() < 7) return std::nullopt;
      return 9 + std::size_t{adu[6]};
    case 0x16:  // mask write register
      return 10;
    case 0x17:
      if (adu.size() < 11) return std::nullopt;
      return 13 + std::size_t{adu[10]};
    case 0x18:  // read FIFO queue
      return 6;
    case 0x2B:
      if (adu.size() < 3) return std::nullopt;
      if (adu[2] == 0x0E) return 7;  // MEI type, read device ID code, object ID
      return std::nullopt;
    default:
      return std::nullopt;
  }
}

bool rtu_request_incomplete(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < 2) return true;
  if (bytes.size() >= rtu_min_adu_size && decode_rtu_adu(bytes).error == RtuFrameError::none)
    return false;
  const auto size = rtu_request_size(bytes);
  if (size) return bytes.size() < *size;
  // The function codes whose size is in a byte that has not arrived yet.
  switch (bytes[1]) {
    case 0x0F:
    case 0x10:
      return bytes.size() < 7;
    case 0x17:
      return bytes.size() < 11;
    case 0x2B:
      return bytes.size() < 3;
    default:
      return false;
  }
}

RtuDecodeResult decode_rtu_adu(std::span<const std::uint8_t> adu) {
  if (adu.size() < rtu_min_adu_size) return {RtuFrameError::too_short, {}};
  if (adu.size() > rtu_max_adu_size) return {RtuFrameError::too_long, {}};
  const std::size_t body = adu.size() - 2;
  const auto received =
      static_cast<std::uint16_t>(adu[body] | (static_cast<std::uint16_t>(adu[body + 1]) << 8));
  if (rtu_crc16(adu.first(body)) != received) {
    const auto expected = rtu_request_size(adu);
    return {expected && adu.size() < *expected ? RtuFrameError::truncated : RtuFrameError::bad_crc,
            {}};
  }
  return {RtuFrameError::none, RtuFrame{adu[0], adu.subspan(1, body - 1)}};
}

std::chrono::nanoseconds rtu_character_time(unsigned baud, unsigned bits_per_character) {
  if (baud == 0) return std::chrono::nanoseconds(0);
  return std::chrono::nanoseconds(std::uint64_t{bits_per_character} * 1'000'000'000ULL / baud);
}

std::chrono::microseconds rtu_silent_interval(unsigned baud, unsigned bits_per_character) {
  if (baud > 19200 || baud == 0) return std::chrono::microseconds(1750);
  const auto t35 = rtu_character_time(baud, bits_per_character) * 7 / 2;
  return std::chrono::ceil<std::chrono::microseconds>(t35);
}

}  // namespace fieldgate::modbus
