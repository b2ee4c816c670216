#include <gtest/gtest.h>

#include "drivers/copley_ascii/copley_family.hpp"

namespace fieldgate {
namespace {

NodeAddress node(int n) {
  return {std::to_string(n), n, 0};
}
Request read(const char* c) {
  return {c, Request::Expect::values, NumberFormat::decimal};
}
Request write(const char* c) {
  return {c, Request::Expect::ack, NumberFormat::decimal};
}

TEST(CopleyInterpret, ValueForARead) {
  const auto r = interpret_copley_reply(node(0), read("g r0x32"), "v -40000\r");
  EXPECT_EQ(r.status, Reply::Status::ok);
  EXPECT_EQ(r.values, std::vector<int64_t>{-40000});
}

TEST(CopleyInterpret, OkForAWrite) {
  EXPECT_EQ(interpret_copley_reply(node(3), write("t 1"), "ok\r").status, Reply::Status::ok);
}

TEST(CopleyInterpret, MismatchedReplyKindIsGarbled) {
  EXPECT_EQ(interpret_copley_reply(node(0), read("g r0x32"), "ok\r").status,
            Reply::Status::garbled);
  EXPECT_EQ(interpret_copley_reply(node(0), write("t 1"), "v 3\r").status, Reply::Status::garbled);
}

TEST(CopleyInterpret, DeviceErrorCarriesCodeAndManualText) {
  const auto r = interpret_copley_reply(node(0), write("t2"), "e 33\r");
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, 33);
  EXPECT_EQ(r.text, "e 33: ASCII command parsing error");
}

TEST(CopleyInterpret, E32FromForwardedNodeMeansUnreachable) {
  const auto r = interpret_copley_reply(node(7), read("g r0x32"), "e 32\r");
  EXPECT_EQ(r.status, Reply::Status::unreachable);
  EXPECT_EQ(r.device_code, 32);
  // On the serial amplifier itself it is an ordinary device error.
  EXPECT_EQ(interpret_copley_reply(node(0), read("g r0x32"), "e 32\r").status,
            Reply::Status::device_error);
}

TEST(CopleyFamily, AddressesAreCanonical) {
  CopleyFamily f;
  std::string error;
  auto a = f.parse_address("5.b", error);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->text, "5.b");
  EXPECT_EQ(a->number, 5);
  EXPECT_EQ(a->axis, 'b');
  EXPECT_FALSE(f.parse_address("200", error));
  EXPECT_NE(error.find("0..127"), std::string::npos);
}

}  // namespace
}  // namespace fieldgate
