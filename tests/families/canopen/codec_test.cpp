// CiA 301 codecs: candump text, data types, NMT, heartbeat, EMCY, abort texts, error frames.
#include <gtest/gtest.h>

#include <linux/can/error.h>

#include "drivers/canopen/canopen_codec.hpp"
#include "drivers/transport/can_frame.hpp"

namespace fieldgate::canopen {
namespace {

TEST(CanFrameText, RoundTrip) {
  for (const char* text : {"602#4000100000000000", "702#05", "000#0102", "702#R", "181#",
                           "20000040#0000000000000000"}) {
    const auto f = parse_frame(text);
    ASSERT_TRUE(f) << text;
    EXPECT_EQ(to_string(*f), text);
  }
  const auto e = parse_frame("20000040#0000000000000000");
  EXPECT_TRUE(e->error);
  EXPECT_EQ(e->id, CAN_ERR_BUSOFF);
  for (const char* bad :
       {"", "#00", "602", "602#0", "800#00", "602#000102030405060708", "6G2#00", "12345678#00"})
    EXPECT_FALSE(parse_frame(bad)) << bad;
}

TEST(CanFrameText, ErrorFrames) {
  auto f = *parse_frame("20000040#0000000000000000");
  auto info = decode_error_frame(f);
  EXPECT_TRUE(info.bus_off);
  EXPECT_EQ(info.text, "bus-off");
  f = *parse_frame("20000004#0030000000000000");  // controller: rx+tx passive
  info = decode_error_frame(f);
  EXPECT_TRUE(info.error_passive);
  EXPECT_FALSE(info.bus_off);
  EXPECT_EQ(info.text, "error passive");
  f = *parse_frame("20000100#0000000000000000");
  EXPECT_TRUE(decode_error_frame(f).restarted);
  f = *parse_frame("20000024#0001000000000000");  // rx overflow + no ack
  info = decode_error_frame(f);
  EXPECT_TRUE(info.rx_overflow);
  EXPECT_EQ(info.text, "controller buffer overflow, no acknowledge");
  EXPECT_FALSE(decode_error_frame(*parse_frame("181#00")).bus_off);
}

TEST(DataTypes, NamesSizesRanges) {
  EXPECT_EQ(parse_data_type("INTEGER32"), DataType::integer32);
  EXPECT_EQ(parse_data_type("VISIBLE_STRING"), DataType::visible_string);
  EXPECT_FALSE(parse_data_type("int32"));
  EXPECT_FALSE(parse_data_type("REAL32"));
  EXPECT_EQ(size_of(DataType::integer24), 3u);
  EXPECT_EQ(size_of(DataType::visible_string), 0u);
  EXPECT_EQ(min_of(DataType::integer8), -128);
  EXPECT_EQ(max_of(DataType::integer8), 127);
  EXPECT_EQ(max_of(DataType::unsigned16), 65535);
  EXPECT_EQ(min_of(DataType::integer24), -8388608);
  EXPECT_EQ(max_of(DataType::unsigned32), 4294967295);
  EXPECT_EQ(max_of(DataType::boolean), 1);
  EXPECT_TRUE(in_range(DataType::unsigned8, 255));
  EXPECT_FALSE(in_range(DataType::unsigned8, 256));
  EXPECT_FALSE(in_range(DataType::unsigned32, -1));
  EXPECT_FALSE(in_range(DataType::visible_string, 0));
}

TEST(DataTypes, LittleEndianValues) {
  EXPECT_EQ(encode_integer(DataType::integer32, 2000), (std::vector<uint8_t>{0xD0, 0x07, 0, 0}));
  EXPECT_EQ(encode_integer(DataType::integer16, -2), (std::vector<uint8_t>{0xFE, 0xFF}));
  EXPECT_EQ(encode_integer(DataType::unsigned24, 0x123456),
            (std::vector<uint8_t>{0x56, 0x34, 0x12}));
  const uint8_t neg[] = {0xFE, 0xFF, 0xFF, 0xFF};
  EXPECT_EQ(decode_integer(DataType::integer32, neg), -2);
  EXPECT_EQ(decode_integer(DataType::unsigned32, neg), 0xFFFFFFFE);
  EXPECT_EQ(decode_integer(DataType::integer8, std::span(neg, 1)), -2);
  EXPECT_EQ(decode_integer(DataType::unsigned8, std::span(neg, 1)), 0xFE);
  const uint8_t i24[] = {0x00, 0x00, 0x80};
  EXPECT_EQ(decode_integer(DataType::integer24, i24), -8388608);
  EXPECT_FALSE(decode_integer(DataType::integer32, std::span(neg, 2)));
  const uint8_t b[] = {0x02};
  EXPECT_EQ(decode_integer(DataType::boolean, b), 1);
}

TEST(Sdo, RequestPayloads) {
  EXPECT_EQ(to_string(sdo_request_frame(2, sdo_upload_request(0x1018, 4))), "602#4018100400000000");
  EXPECT_EQ(to_string(sdo_request_frame(127, sdo_upload_segment_request(true))),
            "67F#7000000000000000");
  const uint8_t one[] = {0x0F};
  EXPECT_EQ(to_string(sdo_request_frame(5, sdo_download_request(0x6040, 0, one))),
            "605#2F4060000F000000");
  EXPECT_EQ(to_string(sdo_request_frame(5, sdo_abort_request(0x6040, 0, 0x05040000))),
            "605#8040600000000405");
}

TEST(Sdo, AbortTexts) {
  EXPECT_EQ(abort_text(0x06020000), "object does not exist in the object dictionary");
  EXPECT_EQ(abort_text(0x06090030), "invalid value for parameter (download only)");
  EXPECT_EQ(abort_text(0x05040000), "SDO protocol timed out");
  EXPECT_EQ(abort_text(0x08000022),
            "data cannot be transferred or stored to the application because of the present "
            "device state");
  EXPECT_EQ(abort_text(0x0609FFFF), "access or parameter error 0x0609FFFF");
  EXPECT_EQ(abort_text(0x12345678), "abort code 0x12345678");
}

TEST(Nmt, FramesAndStates) {
  EXPECT_EQ(to_string(nmt_frame(NmtCommand::start, 2)), "000#0102");
  EXPECT_EQ(to_string(nmt_frame(NmtCommand::reset_node, 0)), "000#8100");
  EXPECT_EQ(to_string(nmt_frame(NmtCommand::enter_pre_operational, 127)), "000#807F");
  auto hb = parse_heartbeat(*parse_frame("703#7F"));
  ASSERT_TRUE(hb);
  EXPECT_EQ(hb->node, 3);
  EXPECT_EQ(hb->state, nmt_state::pre_operational);
  EXPECT_FALSE(hb->toggle);
  EXPECT_EQ(parse_heartbeat(*parse_frame("702#85"))->state, nmt_state::operational);  // toggle
  EXPECT_TRUE(parse_heartbeat(*parse_frame("702#85"))->toggle);
  EXPECT_FALSE(parse_heartbeat(*parse_frame("702#05"))->toggle);
  EXPECT_EQ(parse_heartbeat(*parse_frame("77F#00"))->state, nmt_state::boot_up);
  EXPECT_FALSE(parse_heartbeat(*parse_frame("700#00")));
  EXPECT_FALSE(parse_heartbeat(*parse_frame("702#")));
  EXPECT_FALSE(parse_heartbeat(*parse_frame("702#R")));
  EXPECT_EQ(nmt_state_text(0x05), "operational");
}

TEST(Emergency, ParseAndText) {
  auto e = parse_emergency(*parse_frame("082#1023030000000000"));
  ASSERT_TRUE(e);
  EXPECT_EQ(e->node, 2);
  EXPECT_EQ(e->code, 0x2310);
  EXPECT_EQ(e->error_register, 0x03);
  EXPECT_EQ(emergency_text(0x2310), "current, device output side");
  EXPECT_EQ(emergency_text(0x2000), "current");
  EXPECT_EQ(emergency_text(0x8130), "life guard error or heartbeat error");
  EXPECT_EQ(emergency_text(0x8111), "communication");
  EXPECT_EQ(emergency_text(0x0000), "error reset or no error");
  EXPECT_EQ(emergency_text(0xFF01), "device specific");
  EXPECT_FALSE(parse_emergency(*parse_frame("080#0000000000000000")));  // SYNC
  EXPECT_FALSE(parse_emergency(*parse_frame("082#10")));
}

TEST(Address, NodeIds) {
  std::string error;
  EXPECT_EQ(parse_node_id("1", error), 1);
  EXPECT_EQ(parse_node_id("127", error), 127);
  EXPECT_EQ(parse_node_id("0x20", error), 32);
  EXPECT_FALSE(parse_node_id("0", error));
  EXPECT_EQ(error, "expected a CANopen node ID 1..127, found '0'");
  EXPECT_FALSE(parse_node_id("128", error));
  EXPECT_FALSE(parse_node_id("3.b", error));
}

}  // namespace
}  // namespace fieldgate::canopen
