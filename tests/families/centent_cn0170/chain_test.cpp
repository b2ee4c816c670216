// The family's decision logic without I/O: what goes on the wire for a request, and what the
// lines that come back mean, including unsolicited messages between them.
#include <gtest/gtest.h>

#include <random>

#include "drivers/centent_cn0170/cn0170_chain.hpp"
#include "tests/harness/text_checks.hpp"

namespace fieldgate::cn0170 {
namespace {

Request read(const char* c) {
  return {c, Request::Expect::values, NumberFormat::hex};
}
Request command(const char* c) {
  return {c, Request::Expect::ack, NumberFormat::decimal};
}

// Runs one exchange over canned lines; nullopt if the lines did not end it.
std::optional<Reply> exchange(Chain& chain, const Options& options, int unit, const Request& r,
                              std::vector<std::string> lines, std::string* bytes = nullptr) {
  Plan plan = plan_request(chain, options, unit, r);
  if (bytes) *bytes = plan.bytes;
  if (plan.refused) return plan.refused;
  Exchange ex(chain, unit, std::move(plan), r.command);
  for (const auto& l : lines)
    if (ex.on_line(l)) return ex.reply();
  return std::nullopt;
}

class ChainTest : public ::testing::Test {
 protected:
  void SetUp() override {
    chain.order = {0, 1, 2};
    chain.order_known = true;
  }
  // Unit 1 in a mode that guards it: `blocked` is refused with `code` before it is sent, M?
  // passes, and M1 is sent and confirmed.
  void expect_guarded_until_m1(const Request& blocked, int code) {
    const auto refused = exchange(chain, options, 1, blocked, {});
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->device_code, code);
    EXPECT_FALSE(plan_request(chain, options, 1, read("M?")).refused);
    const auto back = exchange(chain, options, 1, command("M1"), {"1M1\r"});
    ASSERT_TRUE(back);
    EXPECT_EQ(back->status, Reply::Status::ok) << back->text;
  }

  Chain chain;
  Options options;
};

TEST_F(ChainTest, SelectionIsStickyForReads) {
  Plan first = plan_request(chain, options, 2, read("XP?;YP?"));
  EXPECT_EQ(first.bytes, "\r.U2\rXP?;YP?\r");
  Plan second = plan_request(chain, options, 2, read("XV?;YV?"));
  EXPECT_EQ(second.bytes, "\rXV?;YV?\r");
  Plan other = plan_request(chain, options, 0, read("XP?;YP?"));
  EXPECT_EQ(other.bytes, "\r.U0\rXP?;YP?\r");
  EXPECT_EQ(chain.selections, 2u);
  EXPECT_EQ(chain.units[2].counters.selections, 1u);
}

TEST_F(ChainTest, OneSelectionPerUnitForAPollCycleInUnitOrder) {
  for (int cycle = 0; cycle < 3; ++cycle)
    for (int unit : {0, 0, 1, 1, 1, 2, 2})
      (void)plan_request(chain, options, unit, read("XP?;YP?"));
  EXPECT_EQ(chain.selections, 9u);  // 3 per cycle, one per unit
}

TEST_F(ChainTest, CommandsReselectAndAreConfirmed) {
  (void)plan_request(chain, options, 1, read("M?"));
  Plan p = plan_request(chain, options, 1, command("XV=200,2000;X=0FA000H"));
  EXPECT_EQ(p.bytes, "\r.U1\rXV=200,2000;X=0FA000H\rM?\r");
  ASSERT_EQ(p.expected.size(), 1u);
  EXPECT_EQ(p.expected[0].kind, MessageKind::mode);
  options.reselect_for_commands = false;
  options.confirm_commands = false;
  options.leading_cr = false;
  Plan q = plan_request(chain, options, 1, command("XH"));
  EXPECT_EQ(q.bytes, "XH\r");
  EXPECT_TRUE(q.expected.empty());
}

// Positions are "positive only" (§9 #20): a unit that compares an absolute target with its
// position unsigned runs the long way round its 2^32 register (35 minutes at 2000 steps/s) to
// reach a target on the other side of 0. Such moves are refused before anything is sent.
TEST_F(ChainTest, AbsoluteMoveAcrossZeroIsRefused) {
  const auto refused = [&](const char* c) {
    const Plan p = plan_request(chain, options, 1, command(c));
    return p.refused && p.refused->device_code == kInvalidValue;
  };
  // Position not polled yet: the register is 0 after power-up.
  EXPECT_TRUE(refused("XV=200,2000;X=0FFFFF060H"));  // -4000 as the model renders it
  EXPECT_TRUE(refused("X=-5"));
  EXPECT_TRUE(refused("X=0BB8H,Y=0FFFFFC00H"));  // linear: the Y term
  EXPECT_TRUE(refused("X=0BB8H & Y=-1"));
  EXPECT_FALSE(refused("XV=200,2000;X=0BB8H"));
  EXPECT_FALSE(refused("X-0FA0H"));       // relative moves are the way below 0
  EXPECT_TRUE(refused("XP=0FFFFF060H"));  // a negative position cannot be declared either
  EXPECT_FALSE(refused("Y/X=0C0000000H"));
  // A negative target is refused by the codec whatever the position (the register takes
  // positive numbers only); the sign guard covers a positive target from below 0.
  const auto text = plan_request(chain, options, 1, command("X=0FFFFF060H")).refused->text;
  test::expect_contains(text, {"a negative absolute position"});

  // Below 0 now (a relative move went there): targets above 0 cross it, targets below do not.
  ASSERT_TRUE(exchange(chain, options, 1, read("XP?;YP?"), {"1X=FFFFF060h\r", "1Y=00000400h\r"}));
  EXPECT_TRUE(refused("X=0BB8H"));
  EXPECT_TRUE(refused("X=0"));
  const auto crossing = plan_request(chain, options, 1, command("X=0BB8H")).refused->text;
  test::expect_contains(crossing, {"to 3000 from -4000", "move relative"});
  EXPECT_TRUE(refused("X=0FFFFF000H"));  // negative: the codec's refusal
  EXPECT_FALSE(refused("Y=0BB8H"));      // Y is still above 0
  EXPECT_FALSE(refused("X+0FA0H"));
  // Its reset clears the position register: above 0 again.
  Exchange ex(chain, 1, plan_request(chain, options, 1, read("XP?")), "XP?");
  (void)ex.on_line("U1\r");
  EXPECT_FALSE(refused("X=0BB8H"));

  options.guard_position_sign = false;
  ASSERT_TRUE(exchange(chain, options, 1, read("XP?;YP?"), {"1X=FFFFF060h\r", "1Y=00000400h\r"}));
  EXPECT_FALSE(refused("X=0BB8H"));      // the guard is off
  EXPECT_TRUE(refused("X=0FFFFF060H"));  // the codec's refusal is not an option
}

TEST_F(ChainTest, ReadDemultiplexedByPrefixWithMotionWord) {
  const auto r = exchange(chain, options, 2, read("XP?;YP?"), {"2X=00000400h\r", "2Y-00000800h\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::ok);
  EXPECT_EQ(r->values,
            (std::vector<int64_t>{0x400, 0, 0x800, kYMoving | kYCounterClockwise | kMoving,
                                  kYMoving | kYCounterClockwise | kMoving}));
  EXPECT_TRUE(chain.units[2].answering);
}

TEST_F(ChainTest, UnitZeroRepliesWithoutPrefix) {
  const auto r = exchange(chain, options, 0, read("XP?"), {"X+00000001h\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::ok);
  EXPECT_EQ(r->values, (std::vector<int64_t>{1, kXMoving | kMoving, kXMoving | kMoving}));
}

TEST_F(ChainTest, CrLfRepliesAndBlankLinesAreFine) {
  const auto r = exchange(chain, options, 1, read("P1?;P2?"), {"1P1=1\r", "\n", "1P2=0\r", "\n"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values, (std::vector<int64_t>{1, 0}));
}

TEST_F(ChainTest, RejectedStringIsADeviceError) {
  const auto r = exchange(chain, options, 1, command("XQ=5"), {"1\"XQ=5\" ?\r", "1M1\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::device_error);
  EXPECT_EQ(r->device_code, kRejected);
  EXPECT_EQ(r->text, "unit 1 rejected \"XQ=5\" (syntax error; the string was ignored)");
  EXPECT_EQ(chain.units[1].counters.rejects, 1u);
  EXPECT_TRUE(chain.drain_before_next);
}

// A garbled position reply is no value: the exchange fails, and the line must be proved again.
TEST_F(ChainTest, LowerCaseHexPositionIsGarbled) {
  const auto r = exchange(chain, options, 1, read("XP?"), {"1X=001aD303h\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::garbled) << r->text;
  EXPECT_TRUE(r->values.empty());
}

// Under the reading that a unit in Operate Mode (M3) discards the instructions the host sends,
// `M?` -> `M3` after a command is no confirmation that it ran.
TEST_F(ChainTest, ConfirmationShowingOperateModeIsNoConfirmation) {
  const auto r = exchange(chain, options, 1, command("X=1000"), {"1M3\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::device_error);
  EXPECT_EQ(r->device_code, kOperateMode);
  EXPECT_NE(r->text.find("Operate Mode (M3)"), std::string::npos) << r->text;
  EXPECT_EQ(chain.units[1].mode, 3);
  // Motor traffic is refused before it is sent; mode queries and M1 pass and are confirmed.
  ASSERT_NO_FATAL_FAILURE(expect_guarded_until_m1(command("XH"), kOperateMode));
  EXPECT_FALSE(plan_request(chain, options, 1, command("XH")).refused);
}

TEST_F(ChainTest, ConfirmationShowingProgramModeMeansStored) {
  const auto r = exchange(chain, options, 1, command("X=1000"), {"1M2\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::device_error);
  EXPECT_EQ(r->device_code, kStoredInProgram);
  EXPECT_EQ(chain.units[1].mode, 2);
  // Now motor and I/O traffic is refused before it is sent; mode queries and M1 pass.
  ASSERT_NO_FATAL_FAILURE(expect_guarded_until_m1(read("XP?"), kProgramMode));
  EXPECT_EQ(chain.units[1].mode, 1);
}

TEST_F(ChainTest, NeverSendsM2OrItsOwnSelections) {
  EXPECT_EQ(plan_request(chain, options, 1, command("M2")).refused->device_code, kInvalidValue);
  EXPECT_EQ(plan_request(chain, options, 1, command(".U2;X=5")).refused->device_code,
            kInvalidValue);
  EXPECT_EQ(plan_request(chain, options, 1, read("X=5")).refused->text, "'X=5' is not a query");
  EXPECT_EQ(plan_request(chain, options, 1, command("XR3")).refused->text,
            "'XR3': step resolution must be 1, 2, 10 or 125");
}

TEST_F(ChainTest, OverflowWarningBlocksQueuedInstructionsUntilQueueEmpty) {
  // Q* arrives ahead of the reply to a poll: counted, not taken for the reply.
  const auto r = exchange(chain, options, 2, read("XP?"), {"2Q*\r", "2X=00000005h\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values[0], 5);
  EXPECT_TRUE(chain.units[2].queue_full);
  EXPECT_EQ(chain.units[2].counters.overflow_warnings, 1u);
  const auto refused = exchange(chain, options, 2, command("X+100"), {});
  EXPECT_EQ(refused->device_code, kQueueFull);
  // Stops and queries still go.
  EXPECT_FALSE(plan_request(chain, options, 2, command("Q")).refused);
  EXPECT_FALSE(plan_request(chain, options, 2, read("XP?")).refused);
  EXPECT_FALSE(plan_request(chain, options, 1, command("X+100")).refused);
  chain.absorb(parse_message("2*Q"));
  EXPECT_FALSE(chain.units[2].queue_full);
  EXPECT_FALSE(plan_request(chain, options, 2, command("X+100")).refused);
}

TEST_F(ChainTest, ResetOfAnUpstreamUnitLosesTheRequestAtOnce) {
  options.leading_cr = false;
  (void)plan_request(chain, options, 2, read("XP?"));
  ASSERT_EQ(chain.selected, 2);
  const auto r = exchange(chain, options, 2, read("XP?"), {"U1\r"});
  ASSERT_TRUE(r) << "no need to wait out the timeout";
  EXPECT_EQ(r->status, Reply::Status::garbled);
  EXPECT_NE(r->text.find("unit 1 reset (U1)"), std::string::npos) << r->text;
  EXPECT_FALSE(chain.selected);
  EXPECT_EQ(chain.units[1].counters.resets, 1u);
  EXPECT_FALSE(chain.units[1].set_up);
  // The next request selects again.
  EXPECT_EQ(plan_request(chain, options, 2, read("XP?")).bytes, ".U2\rXP?\r");
}

TEST_F(ChainTest, ResetAnsweringOurLeadingCrLetsTheRequestThrough) {
  // The reset unit auto-bauds on the CR that starts every transmission, then takes the .U2.
  const auto r = exchange(chain, options, 2, command("X+100"), {"U1\r", "2M1\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::ok);
  EXPECT_EQ(chain.units[1].counters.resets, 1u);
  // Silence after it: the reset is named in the failure.
  Plan plan = plan_request(chain, options, 2, read("XP?"));
  Exchange ex(chain, 2, plan, "XP?");
  EXPECT_FALSE(ex.on_line("U1\r"));
  EXPECT_EQ(ex.on_timeout("").text, "no reply from unit 2 to 'XP?' after unit 1 reset (U1)");
}

TEST_F(ChainTest, ResetDownstreamDoesNotLoseTheReply) {
  const auto r = exchange(chain, options, 0, read("XP?"), {"U2\r", "X=00000007h\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::ok);
  EXPECT_EQ(r->values[0], 7);
  EXPECT_EQ(chain.units[2].counters.resets, 1u);
  EXPECT_FALSE(chain.selected) << "after a reset no selection is trusted";
}

TEST_F(ChainTest, ReplyFromAnotherUnitMeansItTrappedTheRequest) {
  (void)plan_request(chain, options, 2, read("XP?"));
  const auto r = exchange(chain, options, 2, read("XP?"), {"1X=00000000h\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::garbled);
  EXPECT_EQ(r->text,
            "unit 1 answered 'XP?' meant for unit 2 (it trapped the request: a reset or "
            "a duplicate unit number); selection forgotten");
  EXPECT_FALSE(chain.selected);
  // After an explicit .U2 a reply from unit 1 can only be a late one.
  const auto late = exchange(chain, options, 2, read("XP?"), {"1X=00000000h\r", "2X=00000001h\r"});
  ASSERT_TRUE(late);
  EXPECT_EQ(late->status, Reply::Status::ok);
  EXPECT_EQ(late->values[0], 1);
}

TEST_F(ChainTest, LateReplyOfAnotherKindIsSkipped) {
  const auto r =
      exchange(chain, options, 1, read("XP?"), {"1M1\r", "1XV=0000h\r", "1XP\r", "1X=00000009h\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::ok);
  EXPECT_EQ(r->values[0], 9);
  EXPECT_EQ(chain.units[1].counters.x_done, 1u);
  EXPECT_EQ(chain.stray_lines, 2u);
}

TEST_F(ChainTest, GarbageEndsTheExchange) {
  const auto r = exchange(chain, options, 1, read("XP?"), {"\x13#~z\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, Reply::Status::garbled);
  EXPECT_TRUE(chain.drain_before_next);
  EXPECT_FALSE(chain.selected);
}

TEST_F(ChainTest, TimeoutForgetsTheSelection) {
  Plan plan = plan_request(chain, options, 1, read("XP?;YP?"));
  Exchange silent(chain, 1, plan, "XP?;YP?");
  const Reply r = silent.on_timeout("");
  EXPECT_EQ(r.status, Reply::Status::timeout);
  EXPECT_EQ(r.text, "no reply from unit 1 to 'XP?;YP?'");
  EXPECT_FALSE(chain.selected);
  EXPECT_TRUE(chain.drain_before_next);

  Exchange half(chain, 1, plan, "XP?;YP?");
  EXPECT_FALSE(half.on_line("1X=00000000h\r"));
  EXPECT_EQ(half.on_timeout("").status, Reply::Status::garbled);
  Exchange cut(chain, 1, plan, "XP?;YP?");
  EXPECT_EQ(cut.on_timeout("1X=000").text, "incomplete reply '1X=000' from unit 1 to 'XP?;YP?'");
}

// Seen on the demo under load: unit 2's Y reply was cut ('2Y=0000000', rest '0h' drained as a
// fragment). It was owed anyway, so every later poll took its own Y reply for the late one,
// waited for another, timed out and owed it again: garbled polls for good, the motion word
// never read, a move busy until its timeout.
TEST_F(ChainTest, ReplyCutInsideTheLineIsNotOwed) {
  const auto t0 = std::chrono::steady_clock::now();
  Plan plan = plan_request(chain, options, 2, read("XP?;YP?"));
  Exchange cut(chain, 2, plan, "XP?;YP?");
  EXPECT_FALSE(cut.on_line("2X=00000400h\r"));
  EXPECT_EQ(cut.on_timeout("2Y=0000000").status, Reply::Status::garbled);
  chain.owe(2, cut.owes(), t0);
  EXPECT_TRUE(chain.owed[2].empty());
  chain.absorb(parse_message("0h\r"));  // the rest, drained by the resync
  const auto next =
      exchange(chain, options, 2, read("XP?;YP?"), {"2X=00000400h\r", "2Y=00000800h\r"});
  ASSERT_TRUE(next) << "the poll after the cut reply took its own Y reply for a late one";
  EXPECT_EQ(next->status, Reply::Status::ok);
  // Cut inside the first reply: the second is still on its way whole, and owed.
  Exchange early(chain, 2, plan_request(chain, options, 2, read("XP?;YP?")), "XP?;YP?");
  (void)early.on_timeout("2X=00");
  EXPECT_EQ(early.owes(), std::vector<std::string>{"YP"});
  EXPECT_TRUE(starts_reply("1XP=00", 1, *classify_query("XP?")));
  EXPECT_TRUE(starts_reply("1M", 1, *classify_query("M?")));
  EXPECT_TRUE(starts_reply("A\\X=8", 0, *classify_query("A\\X?")));
  EXPECT_FALSE(starts_reply("1", 1, *classify_query("XP?")));  // too short to tell
  EXPECT_FALSE(starts_reply("2Y=00", 1, *classify_query("YP?")));
  EXPECT_FALSE(starts_reply("1P1=0", 1, *classify_query("P?")));
}

// A reply that never comes (lost, or cut where the key cannot be told) is owed; the next poll
// takes its own reply for the late one and owes it again. The debt keeps its first age through
// that, so it is written off after the window, not renewed by every poll.
TEST_F(ChainTest, DebtRenewedByEachPollIsStillWrittenOff) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto window = std::chrono::milliseconds(250);
  Plan plan = plan_request(chain, options, 2, read("XP?;YP?"));
  Exchange lost(chain, 2, plan, "XP?;YP?");
  EXPECT_FALSE(lost.on_line("2X=00000400h\r"));
  (void)lost.on_timeout("");
  chain.owe(2, lost.owes(), t0);
  ASSERT_EQ(chain.owed[2].size(), 1u);
  int garbled = 0;
  for (int poll = 1; poll <= 20; ++poll) {
    const auto now = t0 + poll * std::chrono::milliseconds(100);
    chain.expire_owed(now, window);
    Exchange ex(chain, 2, plan_request(chain, options, 2, read("XP?;YP?")), "XP?;YP?");
    (void)ex.on_line("2X=00000400h\r");
    if (ex.on_line("2Y=00000800h\r")) {
      EXPECT_EQ(ex.reply().status, Reply::Status::ok);
      break;
    }
    ++garbled;
    (void)ex.on_timeout("");
    chain.owe(2, ex.owes(), ex.paid_debt_since().value_or(now));
  }
  EXPECT_LE(garbled, 2) << "polls kept paying and renewing the same debt";
}

TEST_F(ChainTest, KillGoesToTheFirstUnitOfTheChain) {
  chain.order = {3, 0, 1};
  Plan p = plan_kill(chain, options, 1, {0, 1, 3});
  EXPECT_EQ(p.bytes, "\r.U3\rK\rM?\r");
  EXPECT_EQ(p.reply_unit, 3);
  Exchange ex(chain, 1, std::move(p), "K");
  EXPECT_TRUE(ex.on_line("3M1\r"));
  EXPECT_EQ(ex.reply().status, Reply::Status::ok);
}

TEST_F(ChainTest, KillWithoutChainOrderGoesToEveryUnit) {
  chain.order_known = false;
  chain.units[1].mode = 2;  // stores K in Program Mode: M1 first
  Plan p = plan_kill(chain, options, 1, {0, 1});
  EXPECT_EQ(p.bytes, "\r.U0\rK\r.U1\rM1\rK\rM?\r");
  options.kill_target = Options::KillTarget::every_unit;
  chain.order_known = true;
  EXPECT_EQ(plan_kill(chain, options, 1, {0, 1}).bytes, "\r.U0\rK\r.U1\rM1\rK\r.U2\rK\rM?\r");
}

TEST_F(ChainTest, RenumberingForgetsSelectionAndOrder) {
  Plan p = plan_request(chain, options, 2, command(".U2=5"));
  EXPECT_EQ(p.bytes, "\r.U2\r.U2=5\r");
  EXPECT_TRUE(p.expected.empty());
  EXPECT_FALSE(chain.selected);
  EXPECT_FALSE(chain.order_known);
}

TEST_F(ChainTest, UnsolicitedProgramOutputIsCounted) {
  const auto r = exchange(chain, options, 0, read("M?"), {"1[U1]\r", "112:00.00\r", "M1\r"});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values, std::vector<int64_t>{1});
  EXPECT_EQ(chain.units[1].counters.unsolicited, 2u);
}

TEST_F(ChainTest, CountersOfAUnit) {
  chain.absorb(parse_message("U1"));
  chain.absorb(parse_message("1Q*"));
  chain.absorb(parse_message("1YP"));
  (void)plan_request(chain, options, 1, read("M?"));
  const auto c = counters_of(chain, 1);
  ASSERT_EQ(c.size(), static_cast<std::size_t>(kCounterFields));
  EXPECT_EQ(c[kResets], 1);
  EXPECT_EQ(c[kOverflowWarnings], 1);
  EXPECT_EQ(c[kQueueFullNow], 1);
  EXPECT_EQ(c[kYMoveDone], 1);
  EXPECT_EQ(c[kUnsolicited], 3);
  EXPECT_EQ(c[kSelections], 1);
  EXPECT_EQ(c[kChainPosition], 2);
}

TEST_F(ChainTest, RandomLinesNeverCrashAndAlwaysEndTheExchange) {
  std::mt19937 random(170);
  const std::string alphabet = "XYPVACM=+-?;h0123456789ABCDEF[]U\"*Q/\\ :.\r\n\x01\xff";
  for (int round = 0; round < 2000; ++round) {
    Plan plan = plan_request(chain, options, static_cast<int>(random() % 10), read("XP?;YP?;M?"));
    Exchange ex(chain, 1, plan, "XP?;YP?;M?");
    bool over = false;
    for (int line = 0; line < 20 && !over; ++line) {
      std::string text;
      const auto length = random() % 16;
      for (std::size_t i = 0; i < length; ++i) text += alphabet[random() % alphabet.size()];
      (void)parse_message(text);
      over = ex.on_line(text + "\r");
    }
    const Reply r = over ? ex.reply() : ex.on_timeout("");
    EXPECT_TRUE(r.status != Reply::Status::ok || r.values.size() == 5u);
    chain.units[1].mode = 0;
    chain.units[1].queue_full = false;
  }
}

Model model_with(std::map<std::string, std::string> options) {
  Model m;
  m.name = "m";
  m.options = std::move(options);
  return m;
}

TEST(Cn0170Options, ParsedAndChecked) {
  Diagnostics d;
  const auto o = parse_options(
      model_with(
          {{"overflow_mode", "rts"}, {"confirm_commands", "off"}, {"kill_target", "every_unit"}}),
      d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  EXPECT_EQ(o.overflow, Options::Overflow::rts);
  EXPECT_FALSE(o.confirm_commands);
  EXPECT_EQ(o.kill_target, Options::KillTarget::every_unit);
  EXPECT_TRUE(o.leading_cr);  // the declared default
  (void)parse_options(
      model_with({{"overflow_mode", "loud"}, {"leading_cr", "maybe"}, {"speed", "1"}}), d);
  ASSERT_EQ(d.errors().size(), 3u) << d.to_text();
  const std::string text = d.to_text();
  test::expect_contains(text, {"unknown centent-cn0170 option 'speed'",
                               "option overflow_mode: expected warning, rts or leave, found 'loud'",
                               "option leading_cr: expected true or false, found 'maybe'"});
  Diagnostics contradiction;
  (void)parse_options(model_with({{"overflow_command", "M1+"}}), contradiction);
  ASSERT_EQ(contradiction.errors().size(), 1u);
  EXPECT_EQ(contradiction.errors()[0].message,
            "model m: option overflow_command 'M1+' contradicts overflow_mode warning");
}

}  // namespace
}  // namespace fieldgate::cn0170
