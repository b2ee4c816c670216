#include "gateway/lifecycle/reload_verdict.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace fieldgate {
namespace {

ReloadVerdict rejected_verdict() {
  ReloadVerdict v;
  v.pid = 4242;
  v.reload = 3;
  v.result = ReloadVerdict::Result::rejected;
  v.config_file = "/etc/fieldgate/fieldgate.yaml";
  v.config_number = 2;
  v.config_id = "0123456789abcdef";
  v.messages = {"/etc/fieldgate/fieldgate.yaml:33:15: unknown key 'baud_rate'",
                "a message\nwith a newline"};
  return v;
}

TEST(ReloadVerdict, RoundTripsThroughItsText) {
  const auto parsed = parse_verdict(to_text(rejected_verdict()));
  ASSERT_TRUE(parsed);
  EXPECT_EQ(parsed->pid, 4242);
  EXPECT_EQ(parsed->reload, 3u);
  EXPECT_EQ(parsed->result, ReloadVerdict::Result::rejected);
  EXPECT_EQ(parsed->config_file, "/etc/fieldgate/fieldgate.yaml");
  EXPECT_EQ(parsed->config_number, 2u);
  EXPECT_EQ(parsed->in_force(), "config #2 (0123456789abcdef)");
  ASSERT_EQ(parsed->messages.size(), 2u);
  EXPECT_EQ(parsed->messages[1], "a message with a newline");  // one line per message
}

TEST(ReloadVerdict, AVerdictCutShortIsNoVerdict) {
  const std::string text = to_text(rejected_verdict());
  // Every prefix short of the whole text: a reader racing a writer without the atomic rename.
  for (std::size_t n = 0; n < text.size(); ++n)
    EXPECT_FALSE(parse_verdict(text.substr(0, n))) << "prefix of " << n << " bytes";
  EXPECT_FALSE(parse_verdict("pid=1\nreload=x\nresult=accepted\nconfig_number=1\nend=1\n"));
  EXPECT_FALSE(parse_verdict("pid=1\nreload=1\nresult=maybe\nconfig_number=1\nend=1\n"));
}

TEST(ReloadVerdict, UnknownKeysFromANewerDaemonAreIgnored) {
  const auto parsed =
      parse_verdict("pid=1\nreload=0\nresult=started\nconfig_number=1\nlater=x\nend=1\n");
  ASSERT_TRUE(parsed);
  EXPECT_EQ(parsed->result, ReloadVerdict::Result::started);
}

TEST(ReloadVerdict, FileIsReplacedWhole) {
  const auto dir = std::filesystem::path(testing::TempDir()) / "verdict-test";
  std::filesystem::create_directories(dir);
  const auto path = dir / kVerdictFileName;
  std::string error;
  auto v = rejected_verdict();
  ASSERT_TRUE(write_verdict_file(path, v, error)) << error;
  v.reload = 4;
  v.result = ReloadVerdict::Result::accepted;
  v.messages = {"short"};
  ASSERT_TRUE(write_verdict_file(path, v, error)) << error;
  const auto read = read_verdict_file(path);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->reload, 4u);
  EXPECT_EQ(read->messages, std::vector<std::string>{"short"});
  EXPECT_FALSE(std::filesystem::exists(path.string() + ".new"));
  EXPECT_FALSE(write_verdict_file(dir / "missing" / kVerdictFileName, v, error));
  EXPECT_FALSE(read_verdict_file(dir / "missing" / kVerdictFileName));
  std::filesystem::remove_all(dir);
}

TEST(ReloadVerdict, FingerprintFollowsTheText) {
  const auto dir = std::filesystem::path(testing::TempDir()) / "fingerprint-test";
  std::filesystem::create_directories(dir);
  const auto path = dir / "fieldgate.yaml";
  std::ofstream(path) << "buses: []\n";
  const auto first = config_fingerprint(path);
  std::ofstream(path) << "buses: [ ]\n";
  const auto second = config_fingerprint(path);
  EXPECT_EQ(first.size(), 16u);
  EXPECT_NE(first, second);
  std::ofstream(path) << "buses: []\n";
  EXPECT_EQ(config_fingerprint(path), first);
  EXPECT_EQ(config_fingerprint(dir / "none.yaml"), "");
  std::filesystem::remove_all(dir);
}

TEST(ReloadVerdict, WaitTakesOnlyALaterReload) {
  std::vector<std::optional<ReloadVerdict>> seen;
  ReloadVerdict old_one;
  old_one.reload = 2;
  ReloadVerdict new_one;
  new_one.reload = 3;
  new_one.result = ReloadVerdict::Result::rejected;
  // The daemon has not answered for two reads (an unreadable file, then the old verdict).
  std::vector<std::optional<ReloadVerdict>> script{std::nullopt, old_one, new_one};
  std::size_t reads = 0, pauses = 0;
  const auto verdict =
      wait_for_verdict([&] { return script[std::min(reads++, script.size() - 1)]; }, 2,
                       [&] {
                         ++pauses;
                         return true;
                       });
  ASSERT_TRUE(verdict);
  EXPECT_EQ(verdict->reload, 3u);
  EXPECT_EQ(verdict->result, ReloadVerdict::Result::rejected);
  EXPECT_EQ(pauses, 2u);
}

TEST(ReloadVerdict, WaitEndsWhenThePauseSaysSo) {
  ReloadVerdict old_one;
  old_one.reload = 5;
  int pauses = 0;
  const auto verdict =
      wait_for_verdict([&] { return std::optional(old_one); }, 5, [&] { return ++pauses < 4; });
  EXPECT_FALSE(verdict);
  EXPECT_EQ(pauses, 4);
}

TEST(ReloadVerdict, RuntimeDirectoryFromTheOptionThenSystemd) {
  ::setenv("RUNTIME_DIRECTORY", "/run/fieldgate:/run/other", 1);
  EXPECT_EQ(runtime_directory("/tmp/x"), std::filesystem::path("/tmp/x"));
  EXPECT_EQ(runtime_directory(""), std::filesystem::path("/run/fieldgate"));
  ::unsetenv("RUNTIME_DIRECTORY");
  EXPECT_FALSE(runtime_directory(""));
}

}  // namespace
}  // namespace fieldgate
