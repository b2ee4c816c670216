#include <gtest/gtest.h>

#include "drivers/copley_ascii/copley_family.hpp"
#include "tests/harness/address_checks.hpp"

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

// A reply that cannot answer the request (a late reply to another command) is never taken.
TEST(CopleyInterpret, ImplausibleRepliesAreGarbled) {
  const auto garbled = [](const Request& r, const char* line) {
    return interpret_copley_reply(node(0), r, line).status == Reply::Status::garbled;
  };
  // A value to a set, a copy, a trajectory command, even when the model expects values.
  EXPECT_TRUE(garbled(write("s r0x24 21"), "v 21\r"));
  EXPECT_TRUE(garbled(read("s r0x24 21"), "v 21\r"));
  EXPECT_TRUE(garbled(write("c r0x24"), "v 0\r"));
  // An ok, or a CVM register value, to a get.
  EXPECT_TRUE(garbled(read("g r0x32"), "ok\r"));
  EXPECT_TRUE(garbled(read("g r0x32"), "r 35\r"));
  // Wrong field counts: one value per ordinary variable, nine for 0x6b, two for 0x70-0x77.
  EXPECT_TRUE(garbled(read("g r0x32"), "v 1 2\r"));
  EXPECT_TRUE(garbled(read("g r0x6b"), "v 1\r"));
  EXPECT_TRUE(garbled(read("g r0x72"), "v 258\r"));
  EXPECT_FALSE(garbled(read("g r0x72"), "v 258 0\r"));
  EXPECT_FALSE(garbled(read("g r0x6B"), "v -7936 200 0 775 1550 775 -12774 32763 5813\r"));
  EXPECT_FALSE(garbled(read("g r107"), "v -7936 200 0 775 1550 775 -12774 32763 5813\r"));
  // CVM registers: read answers r n, write answers ok.
  EXPECT_FALSE(garbled(read("i r0"), "r 35\r"));
  EXPECT_TRUE(garbled(read("i r0"), "ok\r"));
  EXPECT_FALSE(garbled(write("i r0 5"), "ok\r"));
  EXPECT_TRUE(garbled(write("i r0 5"), "r 5\r"));
  // Error replies answer anything.
  EXPECT_FALSE(garbled(read("g r0x32"), "e 9\r"));
  EXPECT_FALSE(garbled(write("s r0x24 41"), "e 14\r"));
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
  const auto a = test::expect_address(f, "5.b", "5.b", 5);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->axis, 'b');
  std::string error;
  EXPECT_FALSE(f.parse_address("200", error));
  EXPECT_NE(error.find("0..127"), std::string::npos);
}

}  // namespace
}  // namespace fieldgate
