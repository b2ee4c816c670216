// Parametric checksums against the catalogue's check values (the CRC of "123456789").
#include <gtest/gtest.h>

#include "drivers/protocol_file/checksum.hpp"

namespace fieldgate::protocol_file {
namespace {

uint64_t check_value(std::string_view preset) {
  const auto spec = checksum_preset(preset);
  EXPECT_TRUE(spec) << preset;
  return spec ? compute_checksum(*spec, "123456789") : 0;
}

TEST(Checksum, CataloguePresetsGiveTheirCheckValues) {
  EXPECT_EQ(check_value("crc16-modbus"), 0x4B37u);
  EXPECT_EQ(check_value("crc16-ccitt-false"), 0x29B1u);
  EXPECT_EQ(check_value("crc16-xmodem"), 0x31C3u);
  EXPECT_EQ(check_value("crc8"), 0xF4u);
  EXPECT_EQ(check_value("crc32"), 0xCBF43926u);
  EXPECT_EQ(check_value("sum8"), 0xDDu);
  EXPECT_EQ(check_value("xor8"), 0x31u);
  EXPECT_EQ(check_value("lrc8"), 0x23u);
  EXPECT_FALSE(checksum_preset("crc7"));
}

TEST(Checksum, AnyCrcByItsParameters) {
  // CRC-16/KERMIT: poly 0x1021, reflected, init 0: check 0x2189.
  ChecksumSpec kermit{ChecksumSpec::Algorithm::crc, 16, 0x1021, 0, 0, true,
                      ChecksumSpec::Encoding::hex,  0};
  EXPECT_EQ(compute_checksum(kermit, "123456789"), 0x2189u);
  // CRC-8/MAXIM-DOW: poly 0x31, reflected: check 0xA1.
  ChecksumSpec maxim{ChecksumSpec::Algorithm::crc, 8, 0x31, 0, 0, true,
                     ChecksumSpec::Encoding::hex,  0};
  EXPECT_EQ(compute_checksum(maxim, "123456789"), 0xA1u);
}

TEST(Checksum, EncodingsAndTheSkippedStartCharacter) {
  auto modbus = *checksum_preset("crc16-modbus");
  EXPECT_EQ(encode_checksum(modbus, 0x4B37), std::string("\x37\x4B", 2));
  EXPECT_EQ(checksum_length(modbus), 2u);
  modbus.encoding = ChecksumSpec::Encoding::binary_big;
  EXPECT_EQ(encode_checksum(modbus, 0x4B37), std::string("\x4B\x37", 2));
  auto lrc = *checksum_preset("lrc8");
  EXPECT_EQ(encode_checksum(lrc, 0x0A), "0A");
  lrc.encoding = ChecksumSpec::Encoding::hex_lower;
  EXPECT_EQ(encode_checksum(lrc, 0xAB), "ab");
  auto sum = *checksum_preset("sum8");
  sum.skip = 1;
  EXPECT_EQ(compute_checksum(sum, ":123456789"), 0xDDu);
}

}  // namespace
}  // namespace fieldgate::protocol_file
