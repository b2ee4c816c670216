#include "sim/common/line_device_loop.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "tests/sim/sim_time.hpp"

namespace fieldgate::sim {
namespace {

using namespace std::chrono_literals;
using test::kT0;

// A device that answers "<request>=ok\r" to every CR-terminated request.
struct EchoDevice {
  std::vector<std::string> executed;
  DeviceReply next_reply_extras;

  LineDeviceHooks hooks() {
    LineDeviceHooks hooks;
    hooks.frame = [](std::string_view pending) -> std::size_t {
      const auto cr = pending.find('\r');
      return cr == std::string_view::npos ? 0 : cr + 1;
    };
    hooks.respond = [this](std::string_view request, SimTime) {
      executed.emplace_back(request);
      DeviceReply reply = next_reply_extras;
      reply.bytes = std::string(request.substr(0, request.size() - 1)) + "=ok\r";
      next_reply_extras = {};
      return reply;
    };
    return hooks;
  }
};

// The echo device, its fault switches and the exchange in front of it.
struct EchoLine {
  explicit EchoLine(LineDeviceOptions options = {})
      : exchange(device.hooks(), std::move(options), faults) {}
  EchoDevice device;
  FaultInjection faults;
  LineExchange exchange;
};

std::string drain(LineExchange& exchange, SimTime until) {
  std::string out;
  exchange.advance(until, out);
  return out;
}

TEST(LineExchange, AnswersAtOnceWithoutWireEmulation) {
  EchoLine line;
  line.exchange.receive(kT0, "a\rb");
  EXPECT_EQ(drain(line.exchange, kT0), "a=ok\r");
  line.exchange.receive(kT0 + 1ms, "c\rd\r");
  EXPECT_EQ(drain(line.exchange, kT0 + 1ms), "bc=ok\rd=ok\r");
  EXPECT_EQ(line.device.executed, (std::vector<std::string>{"a\r", "bc\r", "d\r"}));
  EXPECT_TRUE(line.exchange.idle());
}

TEST(LineExchange, WireEmulationPacesRequestTurnaroundAndReply) {
  LineDeviceOptions options;
  options.wire = {true, WireTiming(9600), 500us};
  EchoLine line(options);
  const auto character = WireTiming(9600).character_time();

  line.exchange.receive(kT0, "ab\r");  // 3 characters on the wire
  EXPECT_EQ(drain(line.exchange, kT0 + 3 * character - 1ns), "");
  EXPECT_TRUE(line.device.executed.empty()) << "executed before its bytes had arrived";
  EXPECT_EQ(line.exchange.next_deadline(), kT0 + options.wire.timing.wire_time(3));

  const SimTime executed_at = kT0 + options.wire.timing.wire_time(3);
  EXPECT_EQ(drain(line.exchange, executed_at), "");
  EXPECT_EQ(line.device.executed.size(), 1u);
  // "ab=ok\r" starts after the turnaround; its first byte is usable one character later.
  const SimTime reply_start = executed_at + 500us;
  EXPECT_EQ(line.exchange.next_deadline(), reply_start + options.wire.timing.wire_time(1));
  std::string out;
  while (const auto due = line.exchange.next_deadline()) line.exchange.advance(*due, out);
  EXPECT_EQ(out, "ab=ok\r");
  EXPECT_TRUE(line.exchange.idle());
}

TEST(LineExchange, ReplyAtTheNewBaud) {
  LineDeviceOptions options;
  options.wire = {true, WireTiming(9600), 0us};
  EchoLine line(options);
  line.device.next_reply_extras.new_baud = 115200;
  line.exchange.receive(kT0, "x\r");
  const SimTime executed_at = kT0 + WireTiming(9600).wire_time(2);
  std::string out;
  line.exchange.advance(executed_at, out);
  EXPECT_EQ(line.exchange.baud(), 115200u);
  line.exchange.advance(executed_at + WireTiming(115200).wire_time(5), out);
  EXPECT_EQ(out, "x=ok\r");
}

TEST(LineExchange, SilenceDiscardsRequestsUnexecuted) {
  EchoLine line;
  line.faults.silence = true;
  line.exchange.receive(kT0, "a\r");
  EXPECT_EQ(drain(line.exchange, kT0 + 1s), "");
  EXPECT_TRUE(line.device.executed.empty());
  line.faults.silence = false;
  line.exchange.receive(kT0 + 2s, "b\r");
  EXPECT_EQ(drain(line.exchange, kT0 + 2s), "b=ok\r");
}

TEST(LineExchange, GarbageKeepsLengthAndTerminator) {
  LineDeviceOptions options;
  options.terminators = "\r";
  EchoLine line(options);
  line.faults.garbage_replies = 1;
  line.exchange.receive(kT0, "hello\r");
  const std::string garbage = drain(line.exchange, kT0);
  ASSERT_EQ(garbage.size(), std::string("hello=ok\r").size());
  EXPECT_EQ(garbage.back(), '\r');
  EXPECT_EQ(garbage.find('\r'), garbage.size() - 1);
  EXPECT_NE(garbage, "hello=ok\r");
  EXPECT_EQ(line.faults.garbage_replies, 0u);
  line.exchange.receive(kT0, "hello\r");
  EXPECT_EQ(drain(line.exchange, kT0), "hello=ok\r");
}

TEST(LineExchange, TruncateCutsTheReplyInHalfWithoutTerminator) {
  EchoLine line;
  line.faults.truncated_replies = 2;
  line.exchange.receive(kT0, "v 1200\r");  // reply "v 1200=ok\r"
  EXPECT_EQ(drain(line.exchange, kT0), "v 12");
  line.exchange.receive(kT0, "ab\r");  // "ab=ok" has 5 characters
  EXPECT_EQ(drain(line.exchange, kT0), "ab");
  line.exchange.receive(kT0, "ab\r");
  EXPECT_EQ(drain(line.exchange, kT0), "ab=ok\r");
}

TEST(LineExchange, DelayAndDeviceLatencyHoldTheReply) {
  EchoLine line;
  line.faults.reply_delay = 20ms;
  line.device.next_reply_extras.extra_delay = 5ms;
  line.exchange.receive(kT0, "a\r");
  EXPECT_EQ(drain(line.exchange, kT0 + 24ms), "");
  EXPECT_EQ(line.exchange.next_deadline(), kT0 + 25ms);
  EXPECT_EQ(drain(line.exchange, kT0 + 25ms), "a=ok\r");
}

TEST(LineExchange, DiscardsUnframedInputBeyondTheLimit) {
  LineDeviceOptions options;
  options.max_pending = 8;
  EchoLine line(options);
  line.exchange.receive(kT0, "0123456789");
  line.exchange.receive(kT0, "a\r");
  EXPECT_EQ(drain(line.exchange, kT0), "a=ok\r");
}

TEST(LineExchange, EchoesCharactersAsTheyArrive) {
  EchoDevice device;
  FaultInjection faults;
  LineDeviceHooks hooks = device.hooks();
  hooks.echo = [](std::string_view received) { return std::string(received); };
  LineExchange exchange(hooks, {}, faults);
  exchange.receive(kT0, "ab");
  EXPECT_EQ(drain(exchange, kT0), "ab");
  exchange.receive(kT0, "\r");
  EXPECT_EQ(drain(exchange, kT0), "\rab=ok\r");
}

// Raw bytes (Techno's STOP 0xFF) act alone wherever they arrive, even inside a request, in
// order with the requests around them and without wire time of their own.
TEST(LineExchange, RawBytesActAloneInsideARequest) {
  EchoDevice device;
  FaultInjection faults;
  LineDeviceHooks hooks = device.hooks();
  hooks.raw_bytes = "\xff";
  hooks.raw = [&](char byte, SimTime) {
    device.executed.push_back("raw " + escape_bytes(std::string(1, byte)));
    return DeviceReply{.bytes = "!", .new_baud = {}, .extra_delay = {}};
  };
  LineDeviceOptions options;
  options.wire = {true, WireTiming(9600), 0us};
  LineExchange exchange(hooks, options, faults);
  const SimTime a_arrived = kT0 + options.wire.timing.wire_time(2);
  exchange.receive(kT0,
                   "a\rb\xff"
                   "c");
  // The raw byte waits for "a\r" ahead of it, not for "bc\r" around it.
  std::string out;
  exchange.advance(a_arrived, out);
  EXPECT_EQ(device.executed, (std::vector<std::string>{"a\r", "raw \\xff"}));
  exchange.receive(a_arrived, "\r");
  while (const auto due = exchange.next_deadline()) exchange.advance(*due, out);
  EXPECT_EQ(device.executed, (std::vector<std::string>{"a\r", "raw \\xff", "bc\r"}));
  EXPECT_EQ(out, "a=ok\r!bc=ok\r");
}

TEST(LineExchange, DropsTheByteAfterARequestOnlyRightAfterIt) {
  LineDeviceOptions options;
  options.dropped_after_request = "\n";
  EchoLine line(options);
  line.exchange.receive(kT0, "a\r\nb\r");
  line.exchange.receive(kT0, "\n");
  line.exchange.receive(kT0, "\nc\r");
  EXPECT_EQ(drain(line.exchange, kT0), "a=ok\rb=ok\r\nc=ok\r");
  EXPECT_EQ(line.device.executed, (std::vector<std::string>{"a\r", "b\r", "\nc\r"}));
}

// A device on its own timeline answers later through emit(); faults apply to those replies too.
TEST(LineExchange, RepliesOnTheDeviceTimeline) {
  FaultInjection faults;
  std::optional<SimTime> due;
  LineExchange* line = nullptr;
  LineDeviceHooks hooks;
  hooks.frame = [](std::string_view pending) -> std::size_t {
    const auto cr = pending.find('\r');
    return cr == std::string_view::npos ? 0 : cr + 1;
  };
  hooks.respond = [&](std::string_view, SimTime now) {
    due = now + 10ms;
    return DeviceReply{};
  };
  hooks.advance = [&](SimTime now) {
    if (due && *due <= now) {
      line->emit(*due, "done\r");
      due.reset();
    }
  };
  hooks.next_event = [&] { return due; };
  LineExchange exchange(hooks, {}, faults);
  line = &exchange;
  exchange.receive(kT0, "go\r");
  EXPECT_EQ(drain(exchange, kT0 + 9ms), "");
  EXPECT_EQ(exchange.next_deadline(), kT0 + 10ms);
  EXPECT_EQ(drain(exchange, kT0 + 10ms), "done\r");
  faults.truncated_replies = 1;
  exchange.receive(kT0 + 20ms, "go\r");
  EXPECT_EQ(drain(exchange, kT0 + 30ms), "do");
  EXPECT_FALSE(exchange.next_deadline());
}

TEST(EscapeBytes, ShowsControlCharacters) {
  EXPECT_EQ(escape_bytes("g r0x32\r\n\x01\\"), "g r0x32\\r\\n\\x01\\\\");
}

}  // namespace
}  // namespace fieldgate::sim

namespace fieldgate::sim {
namespace {

// chaos: every request still runs; each reply is late, dropped, garbled or truncated at the
// seeded rates, and the journal records what the device did and which fault was applied.
TEST(LineExchange, ChaosFaultsRepliesButExecutesAndJournalsEveryRequest) {
  EchoDevice device;
  FaultInjection faults;
  ControlChannel control(-1, -1, faults);
  EXPECT_EQ(control.execute("chaos 7 25 25 25 25 80"), "ok chaos");
  EXPECT_EQ(control.execute("chaos 7 50 50 10 0 80").rfind("error: usage", 0), 0u);
  LineDeviceOptions options;
  char* text = nullptr;
  std::size_t size = 0;
  std::FILE* journal = open_memstream(&text, &size);
  options.journal = journal;
  LineExchange exchange(device.hooks(), options, faults);
  std::string out;
  for (int i = 0; i < 200; ++i) {
    const auto t = kT0 + std::chrono::milliseconds(i * 200);
    exchange.receive(t, "r" + std::to_string(i) + "\r");
    exchange.advance(t + 199ms, out);
  }
  std::fclose(journal);
  const std::string lines(text, size);
  std::free(text);
  EXPECT_EQ(device.executed.size(), 200u);
  int late = 0, dropped = 0, garbled = 0, truncated = 0, intact = 0;
  for (int i = 0; i < 200; ++i) {
    const std::string reply = "r" + std::to_string(i) + "=ok\r";
    if (out.find(reply) != std::string::npos) ++intact;
  }
  for (std::size_t p = 0; (p = lines.find('\n', p)) != std::string::npos; ++p) {
    const auto begin = lines.rfind('\n', p - 1);
    const std::string line = lines.substr(begin == std::string::npos ? 0 : begin + 1,
                                          p - (begin == std::string::npos ? 0 : begin + 1));
    EXPECT_NE(line.find("=ok\\r"), std::string::npos) << line;
    late += line.ends_with(" late");
    dropped += line.ends_with(" dropped");
    garbled += line.ends_with(" garbled");
    truncated += line.ends_with(" truncated");
  }
  EXPECT_EQ(late + dropped + garbled + truncated, 200);  // 100 % faulted, every line journaled
  for (int n : {late, dropped, garbled, truncated}) EXPECT_GT(n, 20);
  // Late replies still arrive (80 ms late, inside the 199 ms window); the others never intact.
  EXPECT_EQ(intact, late);
  EXPECT_EQ(control.execute("chaos off"), "ok chaos off");
}

}  // namespace
}  // namespace fieldgate::sim
