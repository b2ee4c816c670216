#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace fieldgate::protocol_file {

// A frame check as a protocol file describes it (docs/protocol-files.md, "Checksums"): any CRC
// by width, polynomial, initial value, reflection and final xor (the Rocksoft model that CRC
// catalogues use), or a sum, xor or LRC (the two's complement of the sum) of the bytes, written
// as hex digits or as binary bytes.
struct ChecksumSpec {
  enum class Algorithm { crc, sum, xor_bytes, lrc };
  enum class Encoding { hex, hex_lower, binary_big, binary_little };
  Algorithm algorithm = Algorithm::crc;
  int width = 8;  // bits: 8, 16 or 32
  uint64_t poly = 0;
  uint64_t init = 0;
  uint64_t xor_out = 0;
  bool reflect = false;  // reflected input and output (CRC-16/MODBUS), as catalogues pair them
  Encoding encoding = Encoding::hex;
  // Characters at the start of a frame that the check does not cover (a start character).
  std::size_t skip = 0;
};

// A named entry of the CRC catalogue (crc16-modbus, crc16-ccitt-false, crc16-xmodem, crc8,
// crc32, sum8, xor8, lrc8); nullopt for any other name.
std::optional<ChecksumSpec> checksum_preset(std::string_view name);
std::string_view checksum_preset_names();

uint64_t compute_checksum(const ChecksumSpec& spec, std::string_view data);
std::string encode_checksum(const ChecksumSpec& spec, uint64_t value);
std::size_t checksum_length(const ChecksumSpec& spec);

}  // namespace fieldgate::protocol_file
