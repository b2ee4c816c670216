// The console's section of the gateway file: off by default, loopback unless told, and off
// loopback only with an allow list and a token file that holds a SHA-256.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "config_file_test.hpp"
#include "gateway/console/console_access.hpp"
#include "text_checks.hpp"

namespace fieldgate {
namespace {

class ConsoleConfigTest : public test::ConfigFileTest {
 protected:
  std::string load_console(const std::string& console, std::optional<LoadedConfig>* out = nullptr) {
    return load("console: " + console + "\nbuses:\n" +
                    test::copley_bus_item(
                        "b", "{device: /dev/null, baud: 115200}", "",
                        "      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n"),
                out);
  }
  void write_token_file(const std::string& text) { std::ofstream(dir_ / "token.sha256") << text; }
};

TEST_F(ConsoleConfigTest, LoopbackByDefault) {
  std::optional<LoadedConfig> c;
  EXPECT_EQ(load_console("{}", &c), "");
  ASSERT_TRUE(c);
  EXPECT_TRUE(c->gateway.console.enabled);
  EXPECT_EQ(c->gateway.console.address, "127.0.0.1");
  EXPECT_TRUE(c->gateway.console.loopback());
  EXPECT_TRUE(c->gateway.console.token_sha256.empty());
}

TEST_F(ConsoleConfigTest, AbsentMeansOff) {
  std::optional<LoadedConfig> c;
  EXPECT_EQ(load("buses:\n" +
                     test::copley_bus_item("b", "{device: /dev/null, baud: 115200}", "",
                                           "      - {name: x, address: 0, model: copley-amplifier, "
                                           "unit_id: 1}\n"),
                 &c),
            "");
  ASSERT_TRUE(c);
  EXPECT_FALSE(c->gateway.console.enabled);
}

TEST_F(ConsoleConfigTest, OffLoopbackNeedsAnAllowListAndATokenFile) {
  test::expect_contains(
      load_console("{listen: 0.0.0.0:9580}"),
      {"console: listening on 0.0.0.0 (not loopback) needs an allow list", "needs token_file"});
}

TEST_F(ConsoleConfigTest, TokenFileIsReadRelativeToTheConfig) {
  const std::string hash = sha256_hex("s3cret");
  write_token_file(hash + "  -\n");
  std::optional<LoadedConfig> c;
  EXPECT_EQ(
      load_console("{listen: 0.0.0.0:9580, allow: [10.0.0.0/8], token_file: token.sha256}", &c),
      "");
  ASSERT_TRUE(c);
  EXPECT_EQ(c->gateway.console.token_sha256, hash);
  EXPECT_FALSE(c->gateway.console.loopback());
}

TEST_F(ConsoleConfigTest, ATokenFileWithoutAHashIsAnErrorAtItsLine) {
  write_token_file("s3cret\n");  // the token itself, not its hash
  test::expect_contains(load_console("{token_file: token.sha256}"),
                        {"gw.yaml:2:", "console token_file:", "64 hex digits"});
  test::expect_contains(load_console("{token_file: missing.sha256}"),
                        {"console token_file: cannot read"});
}

TEST_F(ConsoleConfigTest, BadAllowEntryAndUnknownKey) {
  test::expect_contains(load_console("{allow: [10.0.0.0/33], passwd: x}"),
                        {"console allow:", "unknown key 'passwd'"});
}

TEST(ConsoleAccess, AllowListThenToken) {
  ConsoleConfig c;
  const auto local = asio::ip::make_address("127.0.0.1");
  EXPECT_EQ(check_console_access(c, local, std::nullopt), ConsoleAccess::allowed);
  std::string error;
  c.allow = ClientAllowList({*Cidr::parse("10.0.0.0/8", error)});
  EXPECT_EQ(check_console_access(c, local, std::nullopt), ConsoleAccess::address_refused);
  EXPECT_EQ(check_console_access(c, asio::ip::make_address("::ffff:10.1.2.3"), std::nullopt),
            ConsoleAccess::allowed);
  c.token_sha256 = sha256_hex("s3cret");
  const auto peer = asio::ip::make_address("10.1.2.3");
  EXPECT_EQ(check_console_access(c, peer, std::nullopt), ConsoleAccess::token_missing);
  EXPECT_EQ(check_console_access(c, peer, "guess"), ConsoleAccess::token_wrong);
  EXPECT_EQ(check_console_access(c, peer, "s3cret"), ConsoleAccess::allowed);
}

TEST(ConsoleAccess, TokenFromHeaderOrQuery) {
  EXPECT_EQ(request_token("Bearer abc", "/"), "abc");
  EXPECT_EQ(request_token("", "/events?trace=1&token=a%20b%2B"), "a b+");
  EXPECT_EQ(request_token("", "/events?trace=1"), std::nullopt);
  EXPECT_EQ(request_token("Basic xyz", "/"), std::nullopt);
}

TEST(ConsoleAccess, Sha256OfAKnownText) {
  // FIPS 180-2, appendix B.1.
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

}  // namespace
}  // namespace fieldgate
