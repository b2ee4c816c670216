#include "drivers/protocol_file/checksum.hpp"

#include <fmt/format.h>

namespace fieldgate::protocol_file {

namespace {

uint64_t mask_of(int width) {
  return width >= 64 ? ~uint64_t{0} : (uint64_t{1} << width) - 1;
}

uint64_t reflect_bits(uint64_t v, int width) {
  uint64_t r = 0;
  for (int i = 0; i < width; ++i)
    if (v & (uint64_t{1} << i)) r |= uint64_t{1} << (width - 1 - i);
  return r;
}

uint64_t crc(const ChecksumSpec& s, std::string_view data) {
  const uint64_t mask = mask_of(s.width);
  const uint64_t top = uint64_t{1} << (s.width - 1);
  uint64_t reg = s.init & mask;
  for (const char ch : data) {
    uint64_t byte = static_cast<unsigned char>(ch);
    if (s.reflect) byte = reflect_bits(byte, 8);
    reg ^= byte << (s.width - 8);
    for (int i = 0; i < 8; ++i)
      reg = (reg & top) ? ((reg << 1) ^ s.poly) & mask : (reg << 1) & mask;
  }
  if (s.reflect) reg = reflect_bits(reg, s.width);
  return (reg ^ s.xor_out) & mask;
}

}  // namespace

std::optional<ChecksumSpec> checksum_preset(std::string_view name) {
  using A = ChecksumSpec::Algorithm;
  using E = ChecksumSpec::Encoding;
  if (name == "crc16-modbus")
    return ChecksumSpec{A::crc, 16, 0x8005, 0xFFFF, 0, true, E::binary_little, 0};
  if (name == "crc16-ccitt-false")
    return ChecksumSpec{A::crc, 16, 0x1021, 0xFFFF, 0, false, E::hex, 0};
  if (name == "crc16-xmodem") return ChecksumSpec{A::crc, 16, 0x1021, 0, 0, false, E::hex, 0};
  if (name == "crc8") return ChecksumSpec{A::crc, 8, 0x07, 0, 0, false, E::hex, 0};
  if (name == "crc32")
    return ChecksumSpec{A::crc, 32, 0x04C11DB7, 0xFFFFFFFF, 0xFFFFFFFF, true, E::hex, 0};
  if (name == "sum8") return ChecksumSpec{A::sum, 8, 0, 0, 0, false, E::hex, 0};
  if (name == "xor8") return ChecksumSpec{A::xor_bytes, 8, 0, 0, 0, false, E::hex, 0};
  if (name == "lrc8") return ChecksumSpec{A::lrc, 8, 0, 0, 0, false, E::hex, 0};
  return std::nullopt;
}

std::string_view checksum_preset_names() {
  return "crc16-modbus, crc16-ccitt-false, crc16-xmodem, crc8, crc32, sum8, xor8, lrc8";
}

uint64_t compute_checksum(const ChecksumSpec& s, std::string_view data) {
  data = data.substr(std::min(s.skip, data.size()));
  const uint64_t mask = mask_of(s.width);
  uint64_t v = 0;
  switch (s.algorithm) {
    case ChecksumSpec::Algorithm::crc:
      return crc(s, data);
    case ChecksumSpec::Algorithm::sum:
    case ChecksumSpec::Algorithm::lrc:
      for (const char c : data) v += static_cast<unsigned char>(c);
      if (s.algorithm == ChecksumSpec::Algorithm::lrc) v = ~v + 1;
      return ((v & mask) ^ s.xor_out) & mask;
    case ChecksumSpec::Algorithm::xor_bytes:
      for (const char c : data) v ^= static_cast<unsigned char>(c);
      return ((v & mask) ^ s.xor_out) & mask;
  }
  return 0;
}

std::size_t checksum_length(const ChecksumSpec& s) {
  const std::size_t bytes = static_cast<std::size_t>(s.width / 8);
  return s.encoding == ChecksumSpec::Encoding::hex ||
                 s.encoding == ChecksumSpec::Encoding::hex_lower
             ? bytes * 2
             : bytes;
}

std::string encode_checksum(const ChecksumSpec& s, uint64_t value) {
  const int bytes = s.width / 8;
  switch (s.encoding) {
    case ChecksumSpec::Encoding::hex:
      return fmt::format("{:0{}X}", value, bytes * 2);
    case ChecksumSpec::Encoding::hex_lower:
      return fmt::format("{:0{}x}", value, bytes * 2);
    case ChecksumSpec::Encoding::binary_big:
    case ChecksumSpec::Encoding::binary_little: {
      std::string out(static_cast<std::size_t>(bytes), '\0');
      for (int i = 0; i < bytes; ++i) {
        const int shift =
            s.encoding == ChecksumSpec::Encoding::binary_big ? (bytes - 1 - i) * 8 : i * 8;
        out[static_cast<std::size_t>(i)] = static_cast<char>((value >> shift) & 0xFF);
      }
      return out;
    }
  }
  return {};
}

}  // namespace fieldgate::protocol_file
