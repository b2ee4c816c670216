// PDU codec: requests and responses from the Modbus Application Protocol V1.1b3 examples
// (section 6), every exception path and the quantity boundaries.
#include "gateway/modbus/pdu.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

namespace fieldgate::modbus {
namespace {

using Bytes = std::vector<std::uint8_t>;

Request parse_ok(const Bytes& pdu) {
  auto result = parse_request(pdu);
  if (const auto* e = std::get_if<ExceptionCode>(&result)) {
    ADD_FAILURE() << "unexpected exception " << static_cast<int>(*e);
    return ReadBitsRequest{};
  }
  return std::get<Request>(result);
}

ExceptionCode parse_error(const Bytes& pdu) {
  auto result = parse_request(pdu);
  if (!std::holds_alternative<ExceptionCode>(result)) {
    ADD_FAILURE() << "request was accepted";
    return ExceptionCode::acknowledge;
  }
  return std::get<ExceptionCode>(result);
}

// Bits as the spec lists them: byte i bit j is item 8*i+j.
std::vector<bool> bits_of(const Bytes& bytes, std::size_t count) {
  std::vector<bool> bits(count);
  for (std::size_t i = 0; i < count; ++i) bits[i] = (bytes[i / 8] >> (i % 8)) & 1;
  return bits;
}

Bytes read_pdu(std::uint8_t function, std::uint16_t address, std::uint16_t count) {
  return {function, static_cast<std::uint8_t>(address >> 8), static_cast<std::uint8_t>(address),
          static_cast<std::uint8_t>(count >> 8), static_cast<std::uint8_t>(count)};
}

Bytes write_registers_pdu(std::uint16_t address, std::uint16_t count) {
  Bytes pdu = read_pdu(0x10, address, count);
  pdu.push_back(static_cast<std::uint8_t>(2 * count));
  pdu.resize(pdu.size() + 2 * count, 0x00);
  return pdu;
}

Bytes write_coils_pdu(std::uint16_t address, std::uint16_t count) {
  Bytes pdu = read_pdu(0x0F, address, count);
  pdu.push_back(static_cast<std::uint8_t>((count + 7) / 8));
  pdu.resize(pdu.size() + (count + 7) / 8, 0x00);
  return pdu;
}

Bytes read_write_pdu(std::uint16_t read_address, std::uint16_t read_count,
                     std::uint16_t write_address, std::uint16_t write_count) {
  Bytes pdu = read_pdu(0x17, read_address, read_count);
  const Bytes write = read_pdu(0, write_address, write_count);
  pdu.insert(pdu.end(), write.begin() + 1, write.end());
  pdu.push_back(static_cast<std::uint8_t>(2 * write_count));
  pdu.resize(pdu.size() + 2 * write_count, 0x00);
  return pdu;
}

// --- Spec examples ------------------------------------------------------------------------

TEST(PduSpecExample, ReadCoils) {
  EXPECT_EQ(parse_ok({0x01, 0x00, 0x13, 0x00, 0x13}),
            Request(ReadBitsRequest{BitTable::coils, 19, 19}));
  EXPECT_EQ(encode_read_bits_response(BitTable::coils, bits_of({0xCD, 0x6B, 0x05}, 19)),
            (Bytes{0x01, 0x03, 0xCD, 0x6B, 0x05}));
}

TEST(PduSpecExample, ReadDiscreteInputs) {
  EXPECT_EQ(parse_ok({0x02, 0x00, 0xC4, 0x00, 0x16}),
            Request(ReadBitsRequest{BitTable::discrete_inputs, 196, 22}));
  EXPECT_EQ(encode_read_bits_response(BitTable::discrete_inputs, bits_of({0xAC, 0xDB, 0x35}, 22)),
            (Bytes{0x02, 0x03, 0xAC, 0xDB, 0x35}));
}

TEST(PduSpecExample, ReadHoldingRegisters) {
  EXPECT_EQ(parse_ok({0x03, 0x00, 0x6B, 0x00, 0x03}),
            Request(ReadRegistersRequest{RegisterTable::holding_registers, 107, 3}));
  const std::vector<std::uint16_t> values{0x022B, 0x0000, 0x0064};
  EXPECT_EQ(encode_read_registers_response(FunctionCode::read_holding_registers, values),
            (Bytes{0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64}));
}

TEST(PduSpecExample, ReadInputRegisters) {
  EXPECT_EQ(parse_ok({0x04, 0x00, 0x08, 0x00, 0x01}),
            Request(ReadRegistersRequest{RegisterTable::input_registers, 8, 1}));
  const std::vector<std::uint16_t> values{0x000A};
  EXPECT_EQ(encode_read_registers_response(FunctionCode::read_input_registers, values),
            (Bytes{0x04, 0x02, 0x00, 0x0A}));
}

TEST(PduSpecExample, WriteSingleCoil) {
  EXPECT_EQ(parse_ok({0x05, 0x00, 0xAC, 0xFF, 0x00}), Request(WriteSingleCoilRequest{172, true}));
  EXPECT_EQ(parse_ok({0x05, 0x00, 0xAC, 0x00, 0x00}), Request(WriteSingleCoilRequest{172, false}));
  EXPECT_EQ(encode_write_single_coil_response(172, true), (Bytes{0x05, 0x00, 0xAC, 0xFF, 0x00}));
  EXPECT_EQ(encode_write_single_coil_response(172, false), (Bytes{0x05, 0x00, 0xAC, 0x00, 0x00}));
}

TEST(PduSpecExample, WriteSingleRegister) {
  EXPECT_EQ(parse_ok({0x06, 0x00, 0x01, 0x00, 0x03}), Request(WriteSingleRegisterRequest{1, 3}));
  EXPECT_EQ(encode_write_single_register_response(1, 3), (Bytes{0x06, 0x00, 0x01, 0x00, 0x03}));
}

TEST(PduSpecExample, WriteMultipleCoils) {
  EXPECT_EQ(parse_ok({0x0F, 0x00, 0x13, 0x00, 0x0A, 0x02, 0xCD, 0x01}),
            Request(WriteCoilsRequest{19, bits_of({0xCD, 0x01}, 10)}));
  EXPECT_EQ(encode_write_multiple_response(FunctionCode::write_multiple_coils, 19, 10),
            (Bytes{0x0F, 0x00, 0x13, 0x00, 0x0A}));
}

TEST(PduSpecExample, WriteMultipleRegisters) {
  EXPECT_EQ(parse_ok({0x10, 0x00, 0x01, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01, 0x02}),
            Request(WriteRegistersRequest{1, {0x000A, 0x0102}}));
  EXPECT_EQ(encode_write_multiple_response(FunctionCode::write_multiple_registers, 1, 2),
            (Bytes{0x10, 0x00, 0x01, 0x00, 0x02}));
}

TEST(PduSpecExample, ReadWriteMultipleRegisters) {
  EXPECT_EQ(parse_ok({0x17, 0x00, 0x03, 0x00, 0x06, 0x00, 0x0E, 0x00, 0x03, 0x06, 0x00, 0xFF, 0x00,
                      0xFF, 0x00, 0xFF}),
            Request(ReadWriteRegistersRequest{3, 6, 14, {0x00FF, 0x00FF, 0x00FF}}));
  const std::vector<std::uint16_t> values{0x00FE, 0x0ACD, 0x0001, 0x0003, 0x000D, 0x00FF};
  EXPECT_EQ(
      encode_read_registers_response(FunctionCode::read_write_multiple_registers, values),
      (Bytes{0x17, 0x0C, 0x00, 0xFE, 0x0A, 0xCD, 0x00, 0x01, 0x00, 0x03, 0x00, 0x0D, 0x00, 0xFF}));
}

TEST(PduSpecExample, ExceptionResponse) {
  EXPECT_EQ(encode_exception(0x01, ExceptionCode::illegal_data_address), (Bytes{0x81, 0x02}));
  EXPECT_EQ(encode_exception(0x17, ExceptionCode::gateway_target_failed), (Bytes{0x97, 0x0B}));
}

// --- Function codes -----------------------------------------------------------------------

TEST(PduParse, FunctionCodeOfEachRequest) {
  EXPECT_EQ(function_code(parse_ok(read_pdu(0x01, 0, 1))), FunctionCode::read_coils);
  EXPECT_EQ(function_code(parse_ok(read_pdu(0x02, 0, 1))), FunctionCode::read_discrete_inputs);
  EXPECT_EQ(function_code(parse_ok(read_pdu(0x03, 0, 1))), FunctionCode::read_holding_registers);
  EXPECT_EQ(function_code(parse_ok(read_pdu(0x04, 0, 1))), FunctionCode::read_input_registers);
  EXPECT_EQ(function_code(parse_ok({0x05, 0, 0, 0, 0})), FunctionCode::write_single_coil);
  EXPECT_EQ(function_code(parse_ok({0x06, 0, 0, 0, 0})), FunctionCode::write_single_register);
  EXPECT_EQ(function_code(parse_ok(write_coils_pdu(0, 1))), FunctionCode::write_multiple_coils);
  EXPECT_EQ(function_code(parse_ok(write_registers_pdu(0, 1))),
            FunctionCode::write_multiple_registers);
  EXPECT_EQ(function_code(parse_ok(read_write_pdu(0, 1, 0, 1))),
            FunctionCode::read_write_multiple_registers);
  EXPECT_FALSE(is_write(parse_ok(read_pdu(0x03, 0, 1))));
  EXPECT_TRUE(is_write(parse_ok({0x06, 0, 0, 0, 0})));
}

TEST(PduParse, UnsupportedFunctionsAreIllegalFunction) {
  for (int fc = 0; fc < 256; ++fc) {
    switch (fc) {
      case 0x01:
      case 0x02:
      case 0x03:
      case 0x04:
      case 0x05:
      case 0x06:
      case 0x0F:
      case 0x10:
      case 0x17:
        continue;
    }
    EXPECT_EQ(parse_error({static_cast<std::uint8_t>(fc), 0, 0, 0, 1}),
              ExceptionCode::illegal_function)
        << "function " << fc;
  }
  EXPECT_EQ(parse_error({}), ExceptionCode::illegal_function);
  // 0x2B serves only MEI type 0x0E (read device identification).
  EXPECT_EQ(parse_error({0x2B, 0x0D, 0x01, 0x00}), ExceptionCode::illegal_function);
  EXPECT_EQ(parse_error({0x2B}), ExceptionCode::illegal_function);
}

// --- 0x2B / 0x0E read device identification (spec 6.21) ----------------------------------

TEST(DeviceIdentification, RequestParsesAndBadCodesOrLengthsAreIllegalDataValue) {
  EXPECT_EQ(parse_ok({0x2B, 0x0E, 0x01, 0x00}), Request(ReadDeviceIdentificationRequest{1, 0}));
  EXPECT_EQ(parse_ok({0x2B, 0x0E, 0x04, 0x02}), Request(ReadDeviceIdentificationRequest{4, 2}));
  EXPECT_FALSE(is_write(parse_ok({0x2B, 0x0E, 0x01, 0x00})));
  EXPECT_EQ(parse_error({0x2B, 0x0E, 0x00, 0x00}), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({0x2B, 0x0E, 0x05, 0x00}), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({0x2B, 0x0E, 0x01}), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({0x2B, 0x0E, 0x01, 0x00, 0x00}), ExceptionCode::illegal_data_value);
}

const DeviceIdentification kObjects{
    {0x00, "Company identification"}, {0x01, "Product code XX"}, {0x02, "V2.11"}, {0x05, "model"}};

TEST(DeviceIdentification, BasicStreamMatchesTheSpecExample) {
  // Spec 6.21 example: basic stream from object 0; conformity 0x82 as a regular object exists.
  Bytes expected{0x2B, 0x0E, 0x01, 0x82, 0x00, 0x00, 0x03, 0x00, 0x16};
  for (char c : std::string("Company identification")) expected.push_back(std::uint8_t(c));
  expected.insert(expected.end(), {0x01, 0x0F});
  for (char c : std::string("Product code XX")) expected.push_back(std::uint8_t(c));
  expected.insert(expected.end(), {0x02, 0x05});
  for (char c : std::string("V2.11")) expected.push_back(std::uint8_t(c));
  EXPECT_EQ(encode_device_identification_response({1, 0}, kObjects), expected);
}

TEST(DeviceIdentification, RegularStreamStartsAtTheObjectAskedForOrAtZero) {
  const Bytes from_two = encode_device_identification_response({2, 0x02}, kObjects);
  ASSERT_GE(from_two.size(), 7u);
  EXPECT_EQ(from_two[6], 2);  // V2.11 and model
  EXPECT_EQ(from_two[7], 0x02);
  // An id that is no object restarts the stream at object 0.
  const Bytes unknown = encode_device_identification_response({2, 0x40}, kObjects);
  EXPECT_EQ(unknown[6], 4);
  EXPECT_EQ(unknown[7], 0x00);
  // Basic category: regular objects are left out.
  EXPECT_EQ(encode_device_identification_response({1, 0x05}, kObjects)[6], 3);
}

TEST(DeviceIdentification, IndividualAccess) {
  const Bytes one = encode_device_identification_response({4, 0x05}, kObjects);
  EXPECT_EQ(one,
            (Bytes{0x2B, 0x0E, 0x04, 0x82, 0x00, 0x00, 0x01, 0x05, 0x05, 'm', 'o', 'd', 'e', 'l'}));
  EXPECT_EQ(encode_device_identification_response({4, 0x03}, kObjects), (Bytes{0xAB, 0x02}));
}

TEST(DeviceIdentification, LongObjectsAreCutAndStreamsContinueWithMoreFollows) {
  DeviceIdentification big{
      {0x00, std::string(300, 'v')}, {0x01, std::string(200, 'p')}, {0x02, "1.0"}};
  const Bytes first = encode_device_identification_response({1, 0}, big);
  EXPECT_LE(first.size(), max_pdu_size);
  EXPECT_EQ(first[4], 0xFF);  // more follows
  EXPECT_EQ(first[5], 0x01);  // from object 1
  EXPECT_EQ(first[6], 1);
  const Bytes second = encode_device_identification_response({1, first[5]}, big);
  EXPECT_LE(second.size(), max_pdu_size);
  EXPECT_EQ(second[4], 0x00);
  EXPECT_EQ(second[6], 2);
}

// --- Quantity and address limits ----------------------------------------------------------

struct ReadLimit {
  std::uint8_t function;
  std::uint16_t max;
};

void PrintTo(const ReadLimit& limit, std::ostream* os) {
  *os << "function " << int(limit.function) << ", at most " << limit.max;
}

class PduReadLimits : public ::testing::TestWithParam<ReadLimit> {};

TEST_P(PduReadLimits, QuantityAndAddressBoundaries) {
  const auto [fc, max] = GetParam();
  parse_ok(read_pdu(fc, 0, 1));
  parse_ok(read_pdu(fc, 0, max));
  EXPECT_EQ(parse_error(read_pdu(fc, 0, 0)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(read_pdu(fc, 0, max + 1)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(read_pdu(fc, 0, 0xFFFF)), ExceptionCode::illegal_data_value);
  // The last item may be 0xFFFF, never beyond.
  parse_ok(read_pdu(fc, 0xFFFF, 1));
  parse_ok(read_pdu(fc, static_cast<std::uint16_t>(0x10000 - max), max));
  EXPECT_EQ(parse_error(read_pdu(fc, 0xFFFF, 2)), ExceptionCode::illegal_data_address);
  EXPECT_EQ(parse_error(read_pdu(fc, static_cast<std::uint16_t>(0x10000 - max + 1), max)),
            ExceptionCode::illegal_data_address);
  // A bad quantity is reported before the address (spec state diagrams).
  EXPECT_EQ(parse_error(read_pdu(fc, 0xFFFF, 0)), ExceptionCode::illegal_data_value);
  // Length must be exact.
  Bytes longer = read_pdu(fc, 0, 1);
  longer.push_back(0);
  EXPECT_EQ(parse_error(longer), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({fc, 0x00, 0x00, 0x00}), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({fc}), ExceptionCode::illegal_data_value);
}

INSTANTIATE_TEST_SUITE_P(AllReads, PduReadLimits,
                         ::testing::Values(ReadLimit{0x01, 2000}, ReadLimit{0x02, 2000},
                                           ReadLimit{0x03, 125}, ReadLimit{0x04, 125}),
                         [](const auto& info) {
                           return "fc" + std::to_string(info.param.function);
                         });

TEST(PduParse, WriteSingleCoilAcceptsOnlyFF00And0000) {
  for (std::uint16_t value : {0x0001, 0x00FF, 0xFF01, 0xFFFF, 0x1234, 0x0100}) {
    EXPECT_EQ(parse_error({0x05, 0x00, 0x01, static_cast<std::uint8_t>(value >> 8),
                           static_cast<std::uint8_t>(value)}),
              ExceptionCode::illegal_data_value)
        << value;
  }
  parse_ok({0x05, 0xFF, 0xFF, 0xFF, 0x00});  // address 0xFFFF is a valid coil
  EXPECT_EQ(parse_error({0x05, 0x00, 0x01, 0xFF}), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({0x05, 0x00, 0x01, 0xFF, 0x00, 0x00}), ExceptionCode::illegal_data_value);
}

TEST(PduParse, WriteSingleRegisterLength) {
  EXPECT_EQ(parse_ok({0x06, 0xFF, 0xFF, 0xAB, 0xCD}),
            Request(WriteSingleRegisterRequest{0xFFFF, 0xABCD}));
  EXPECT_EQ(parse_error({0x06, 0x00, 0x01, 0x00}), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({0x06, 0x00, 0x01, 0x00, 0x03, 0x00}), ExceptionCode::illegal_data_value);
}

TEST(PduParse, WriteMultipleRegistersLimits) {
  EXPECT_EQ(std::get<WriteRegistersRequest>(parse_ok(write_registers_pdu(0, 123))).values.size(),
            123u);
  parse_ok(write_registers_pdu(0xFFFF, 1));
  EXPECT_EQ(parse_error(write_registers_pdu(0, 0)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(write_registers_pdu(0, 124)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(write_registers_pdu(0xFFFF, 2)), ExceptionCode::illegal_data_address);

  Bytes bad_count = write_registers_pdu(0, 2);
  bad_count[5] = 3;  // byte count disagrees with the quantity
  EXPECT_EQ(parse_error(bad_count), ExceptionCode::illegal_data_value);
  Bytes short_data = write_registers_pdu(0, 2);
  short_data.pop_back();
  EXPECT_EQ(parse_error(short_data), ExceptionCode::illegal_data_value);
  Bytes extra_data = write_registers_pdu(0, 2);
  extra_data.push_back(0);
  EXPECT_EQ(parse_error(extra_data), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({0x10, 0x00, 0x00, 0x00, 0x01}), ExceptionCode::illegal_data_value);
}

TEST(PduParse, WriteMultipleCoilsLimits) {
  EXPECT_EQ(std::get<WriteCoilsRequest>(parse_ok(write_coils_pdu(0, 1968))).values.size(), 1968u);
  parse_ok(write_coils_pdu(0xFFFF, 1));
  EXPECT_EQ(parse_error(write_coils_pdu(0, 0)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(write_coils_pdu(0, 1969)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(write_coils_pdu(0xFFF8, 9)), ExceptionCode::illegal_data_address);

  Bytes bad_count = write_coils_pdu(0, 9);  // needs 2 bytes
  bad_count[5] = 1;
  bad_count.pop_back();
  EXPECT_EQ(parse_error(bad_count), ExceptionCode::illegal_data_value);
  Bytes short_data = write_coils_pdu(0, 9);
  short_data.pop_back();
  EXPECT_EQ(parse_error(short_data), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({0x0F, 0x00, 0x00, 0x00, 0x01}), ExceptionCode::illegal_data_value);
}

TEST(PduParse, WriteMultipleCoilsIgnoresPaddingBits) {
  // Tolerant reading: the spec asks for zero padding but a stray bit must not reject the write.
  const auto r = std::get<WriteCoilsRequest>(parse_ok({0x0F, 0x00, 0x00, 0x00, 0x03, 0x01, 0xFD}));
  EXPECT_EQ(r.values, (std::vector<bool>{true, false, true}));
}

TEST(PduParse, ReadWriteRegistersLimits) {
  parse_ok(read_write_pdu(0, 125, 0, 121));
  parse_ok(read_write_pdu(0xFFFF, 1, 0xFFFF, 1));
  EXPECT_EQ(parse_error(read_write_pdu(0, 0, 0, 1)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(read_write_pdu(0, 126, 0, 1)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(read_write_pdu(0, 1, 0, 0)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(read_write_pdu(0, 1, 0, 122)), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error(read_write_pdu(0xFFFF, 2, 0, 1)), ExceptionCode::illegal_data_address);
  EXPECT_EQ(parse_error(read_write_pdu(0, 1, 0xFFFF, 2)), ExceptionCode::illegal_data_address);

  Bytes bad_count = read_write_pdu(0, 1, 0, 2);
  bad_count[9] = 2;
  EXPECT_EQ(parse_error(bad_count), ExceptionCode::illegal_data_value);
  Bytes short_data = read_write_pdu(0, 1, 0, 2);
  short_data.pop_back();
  EXPECT_EQ(parse_error(short_data), ExceptionCode::illegal_data_value);
  EXPECT_EQ(parse_error({0x17, 0, 0, 0, 1, 0, 0, 0, 1}), ExceptionCode::illegal_data_value);
}

// --- Response encoders at the limits ------------------------------------------------------

TEST(PduEncode, LargestResponsesFitAPdu) {
  const std::vector<bool> bits(2000, true);
  const Bytes coils = encode_read_bits_response(BitTable::coils, bits);
  EXPECT_EQ(coils.size(), 2u + 250u);
  EXPECT_EQ(coils[1], 250);
  EXPECT_EQ(coils.back(), 0xFF);
  const std::vector<std::uint16_t> registers(125, 0xBEEF);
  const Bytes holding =
      encode_read_registers_response(FunctionCode::read_holding_registers, registers);
  EXPECT_EQ(holding.size(), 2u + 250u);
  EXPECT_EQ(holding[1], 250);
  EXPECT_LE(holding.size(), max_pdu_size);
}

TEST(PduEncode, PartialLastByteIsZeroPadded) {
  EXPECT_EQ(encode_read_bits_response(BitTable::coils, {true, true, true}),
            (Bytes{0x01, 0x01, 0x07}));
  EXPECT_EQ(encode_read_bits_response(
                BitTable::discrete_inputs,
                std::vector<bool>{false, false, false, false, false, false, false, false, true}),
            (Bytes{0x02, 0x02, 0x00, 0x01}));
}

TEST(PduEncode, ExceptionCodeValues) {
  EXPECT_EQ(static_cast<int>(ExceptionCode::illegal_function), 0x01);
  EXPECT_EQ(static_cast<int>(ExceptionCode::illegal_data_address), 0x02);
  EXPECT_EQ(static_cast<int>(ExceptionCode::illegal_data_value), 0x03);
  EXPECT_EQ(static_cast<int>(ExceptionCode::server_device_failure), 0x04);
  EXPECT_EQ(static_cast<int>(ExceptionCode::acknowledge), 0x05);
  EXPECT_EQ(static_cast<int>(ExceptionCode::server_busy), 0x06);
  EXPECT_EQ(static_cast<int>(ExceptionCode::gateway_path_unavailable), 0x0A);
  EXPECT_EQ(static_cast<int>(ExceptionCode::gateway_target_failed), 0x0B);
  EXPECT_EQ(to_string(ExceptionCode::gateway_target_failed),
            "gateway target device failed to respond");
}

}  // namespace
}  // namespace fieldgate::modbus
