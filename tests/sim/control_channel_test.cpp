#include "sim/common/control_channel.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <string>
#include <vector>

namespace fieldgate::sim {
namespace {

using namespace std::chrono_literals;

TEST(ControlChannel, GenericCommandsSetTheFaults) {
  FaultInjection faults;
  ControlChannel control(-1, -1, faults);
  EXPECT_EQ(control.execute("silence on"), "ok silence on");
  EXPECT_TRUE(faults.silence);
  EXPECT_EQ(control.execute("  silence   off "), "ok silence off");
  EXPECT_FALSE(faults.silence);
  EXPECT_EQ(control.execute("garbage 3"), "ok garbage 3");
  EXPECT_EQ(faults.garbage_replies, 3u);
  EXPECT_EQ(control.execute("truncate 0x2"), "ok truncate 2");
  EXPECT_EQ(faults.truncated_replies, 2u);
  EXPECT_EQ(control.execute("delay 250"), "ok delay 250");
  EXPECT_EQ(faults.reply_delay, 250ms);
  EXPECT_FALSE(control.quit_requested());
  EXPECT_EQ(control.execute("quit"), "ok quit");
  EXPECT_TRUE(control.quit_requested());
}

TEST(ControlChannel, RejectsMalformedCommands) {
  FaultInjection faults;
  ControlChannel control(-1, -1, faults);
  EXPECT_EQ(control.execute("silence maybe").rfind("error:", 0), 0u);
  EXPECT_EQ(control.execute("garbage").rfind("error:", 0), 0u);
  EXPECT_EQ(control.execute("garbage -1").rfind("error:", 0), 0u);
  EXPECT_EQ(control.execute("delay x").rfind("error:", 0), 0u);
  EXPECT_EQ(control.execute("frobnicate 3").rfind("error: unknown command", 0), 0u);
  EXPECT_EQ(faults.garbage_replies, 0u);
}

TEST(ControlChannel, PassesOtherVerbsToTheFamily) {
  FaultInjection faults;
  std::vector<std::string> seen;
  ControlChannel control(
      -1, -1, faults,
      [&](std::string_view verb,
          std::span<const std::string> arguments) -> std::optional<std::string> {
        if (verb != "node-off") return std::nullopt;
        seen.assign(arguments.begin(), arguments.end());
        return "ok node-off";
      },
      "node-off N  family help\n");
  EXPECT_EQ(control.execute("node-off 3"), "ok node-off");
  EXPECT_EQ(seen, std::vector<std::string>{"3"});
  EXPECT_EQ(control.execute("node-on 3").rfind("error: unknown command", 0), 0u);
  const std::string help = control.execute("help");
  EXPECT_NE(help.find("# silence on|off"), std::string::npos);
  EXPECT_NE(help.find("# node-off N  family help"), std::string::npos);
  EXPECT_EQ(help.substr(help.size() - 7), "ok help");
}

TEST(ControlChannel, ReadsLinesFromItsInputAndRepliesOnItsOutput) {
  int in[2];
  int out[2];
  ASSERT_EQ(::pipe(in), 0);
  ASSERT_EQ(::pipe(out), 0);
  FaultInjection faults;
  ControlChannel control(in[0], out[1], faults);
  const std::string commands = "garbage 2\r\n\nsilence o";
  ASSERT_EQ(::write(in[1], commands.data(), commands.size()),
            static_cast<ssize_t>(commands.size()));
  control.on_readable();
  EXPECT_EQ(faults.garbage_replies, 2u);
  EXPECT_FALSE(faults.silence);
  ASSERT_EQ(::write(in[1], "n\n", 2), 2);
  control.on_readable();
  EXPECT_TRUE(faults.silence);
  ::close(in[1]);
  control.on_readable();
  EXPECT_EQ(control.input_fd(), -1) << "end of input stops the polling, not the simulator";
  EXPECT_FALSE(control.quit_requested());
  char buffer[256];
  const ssize_t n = ::read(out[0], buffer, sizeof buffer);
  EXPECT_EQ(std::string(buffer, static_cast<std::size_t>(n)), "ok garbage 2\nok silence on\n");
  ::close(in[0]);
  ::close(out[0]);
  ::close(out[1]);
}

TEST(ParseControlInteger, DecimalHexAndNegative) {
  EXPECT_EQ(parse_control_integer("512"), 512);
  EXPECT_EQ(parse_control_integer("0x200"), 512);
  EXPECT_EQ(parse_control_integer("-3"), -3);
  EXPECT_FALSE(parse_control_integer(""));
  EXPECT_FALSE(parse_control_integer("--3"));
  EXPECT_FALSE(parse_control_integer("+3"));
  EXPECT_FALSE(parse_control_integer("3x"));
  EXPECT_FALSE(parse_control_integer("0x"));
}

}  // namespace
}  // namespace fieldgate::sim
