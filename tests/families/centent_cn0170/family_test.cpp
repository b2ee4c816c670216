// CententFamily through a real Link against the simulated chain, in one process: the family
// writes to the shared fake line (tests/harness/fake_line.hpp), the DaisyChain answers.
#include <gtest/gtest.h>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <fmt/format.h>

#include <random>
#include <thread>

#include "drivers/centent_cn0170/cn0170_family.hpp"
#include "fake_line.hpp"
#include "sim/centent/daisy_chain.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

class FamilyOnChain : public ::testing::Test {
 protected:
  void start(std::vector<int> units, sim::centent::ChainOptions options = {},
             std::vector<std::string> configured = {"0", "1", "2"}) {
    options.units = std::move(units);
    chain_ = std::make_unique<sim::centent::DaisyChain>(options, sim::SimClock::now());
    transport_ = std::make_unique<test::FakeLine>(io_, "test-pair", 0);
    transport_->keep_order();  // late replies keep their order, as a chain delivers them
    transport_->set_far_end([this](std::string_view bytes) { hear(bytes); });
    link_ = std::make_unique<Link>(*transport_);
    std::string error;
    Model model;  // no options: the defaults
    model.family = "centent-cn0170";
    for (const auto& c : configured) {
      const NodeAddress& node = nodes_[std::stoi(c)] = *family_.parse_address(c, error);
      family_.configure_node(node, model);
    }
    run(family_.on_link_open(*link_, timing_));
  }
  // Units 0 and 1 on the chain, unit 1 put in `mode` (M2, M3) behind the family's back.
  void start_with_unit_1_in(const std::string& mode) {
    start({0, 1});
    chain_->handle(".U1\r", sim::SimClock::now());
    chain_->handle(mode + "\r", sim::SimClock::now());
  }

  // The chain's side: frames host lines and answers them.
  void hear(std::string_view bytes) {
    pending_.append(bytes);
    while (const auto length = sim::centent::DaisyChain::frame(pending_)) {
      const std::string line = pending_.substr(0, length);
      pending_.erase(0, length);
      wire_ += line;
      transport_->deliver(chain_->handle(line, sim::SimClock::now()).bytes, reply_delay_);
    }
  }

  template <typename T>
  T run(asio::awaitable<T> work) {
    return test::run(io_, std::move(work));
  }

  Reply call(int unit, std::string command, Request::Expect expect = Request::Expect::values,
             bool bus_wide = false) {
    Request r{std::move(command), expect, NumberFormat::hex, bus_wide};
    return run(family_.transact(*link_, nodes_.at(unit), r, timing_));
  }
  Reply command(int unit, std::string c) { return call(unit, std::move(c), Request::Expect::ack); }
  std::uint64_t selections() const { return chain_->stats().selections; }

  asio::io_context io_;
  std::unique_ptr<sim::centent::DaisyChain> chain_;
  std::unique_ptr<test::FakeLine> transport_;
  std::unique_ptr<Link> link_;
  CententFamily family_;
  std::map<int, NodeAddress> nodes_;
  LinkTiming timing_{30ms, 10ms};
  // What the family noted on the link so far, a line each: "level text".
  const std::string& log() {
    for (const auto& note : link_->take_notes())
      log_ += std::to_string(note.level) + " " + note.text + "\n";
    return log_;
  }
  std::string log_;
  std::string wire_;
  std::chrono::milliseconds reply_delay_{0};
  std::string pending_;
};

TEST_F(FamilyOnChain, LinkOpenAutobaudsAndDiscoversTheChain) {
  sim::centent::ChainOptions o;
  o.power_up = true;
  start({0, 1, 4}, o, {"0", "1", "2"});
  EXPECT_EQ(wire_, "\r.U?\r");
  EXPECT_NE(log().find("5 centent-cn0170 chain: auto-baud CR answered by unit(s) 0, 1, 4"),
            std::string::npos)
      << log();
  EXPECT_NE(log().find("chain order from .U?: 0, 1, 4"), std::string::npos) << log();
  EXPECT_NE(log().find("4 centent-cn0170 chain: unit 2 is configured but did not "
                       "answer .U?"),
            std::string::npos)
      << log();
  EXPECT_NE(log().find("unit 4 is on the chain but not configured"), std::string::npos) << log();
  EXPECT_EQ(family_.chain().chain_position(4), 3);
}

TEST_F(FamilyOnChain, FirstContactChecksModeAndSetsWarningMode) {
  start({0, 1, 2});
  wire_.clear();
  const Reply r = call(1, "XP?;YP?");
  ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(wire_, "\r.U1\rM?\r\r.U1\rM1\\-\rM?\r\rXP?;YP?\r");
  EXPECT_EQ(r.values, (std::vector<int64_t>{0, 0, 0, 0, 0}));
  wire_.clear();
  (void)call(1, "XP?;YP?");
  EXPECT_EQ(wire_, "\rXP?;YP?\r") << "set up once; selection sticky";
}

TEST_F(FamilyOnChain, PlainOverflowMnemonicWhenTheBackslashFormIsRejected) {
  sim::centent::ChainOptions o;
  o.unit.accept_backslash_overflow = false;
  start({0, 1}, o, {"0", "1"});
  ASSERT_EQ(call(0, "M?").status, Reply::Status::ok);
  EXPECT_NE(wire_.find("M1-\r"), std::string::npos) << wire_;
  EXPECT_NE(log().find("unit 0: overflow warning mode set (M1-)"), std::string::npos) << log();
  EXPECT_EQ(family_.chain().units[0].counters.rejects, 1u);
}

TEST_F(FamilyOnChain, PollCycleNeedsOneSelectionPerUnit) {
  start({0, 1, 2});
  for (int unit : {0, 1, 2}) ASSERT_EQ(call(unit, "M?").status, Reply::Status::ok);
  const auto before = selections();
  for (int cycle = 0; cycle < 10; ++cycle)
    for (int unit : {0, 1, 2}) {
      ASSERT_EQ(call(unit, "XP?;YP?").status, Reply::Status::ok);
      ASSERT_EQ(call(unit, "XV?;YV?").status, Reply::Status::ok);
      ASSERT_EQ(call(unit, "@counters").status, Reply::Status::ok);
    }
  EXPECT_EQ(selections() - before, 30u);
}

TEST_F(FamilyOnChain, MoveIsConfirmedAndRuns) {
  start({0, 1, 2});
  const Reply r = command(2, "XV=200,4000;X=0FA000H");
  ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
  const Reply moving = call(2, "XP?;YP?");
  ASSERT_EQ(moving.status, Reply::Status::ok);
  EXPECT_EQ(moving.values[4] & cn0170::kXMoving, cn0170::kXMoving);
  EXPECT_FALSE(chain_->unit_at(1).moving('X', sim::SimClock::now()));
}

TEST_F(FamilyOnChain, RejectedCommandIsADeviceErrorAndTheNextRequestIsClean) {
  start({0, 1, 2});
  const Reply r = command(1, "XQ=5");
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, cn0170::kRejected);
  const Reply next = call(1, "XP?");
  EXPECT_EQ(next.status, Reply::Status::ok) << next.text;
}

TEST_F(FamilyOnChain, MissingUnitTimesOutAndOthersAnswer) {
  start({0, 1}, {}, {"0", "1", "2"});
  const Reply r = call(2, "XP?;YP?");
  EXPECT_EQ(r.status, Reply::Status::timeout) << r.text;
  EXPECT_EQ(r.text, "no reply from unit 2 to 'M?'");
  EXPECT_EQ(call(1, "XP?").status, Reply::Status::ok);
  // @counters of an unanswering unit probes it instead of pretending it is there.
  EXPECT_EQ(call(2, "@counters").status, Reply::Status::timeout);
}

TEST_F(FamilyOnChain, ResetMessageResynchronisesTheSelection) {
  start({0, 1, 2});
  ASSERT_EQ(call(2, "XP?").status, Reply::Status::ok);
  const auto sel = selections();
  chain_->control("reset", std::vector<std::string>{"1"}, sim::SimClock::now());
  // The leading CR auto-bauds unit 1, which answers U1 and selects itself: it traps the query
  // meant for unit 2 and its prefixed reply gives it away.
  const Reply lost = call(2, "XP?");
  EXPECT_EQ(lost.status, Reply::Status::garbled);
  EXPECT_NE(lost.text.find("unit 1 answered 'XP?' meant for unit 2"), std::string::npos)
      << lost.text;
  EXPECT_EQ(family_.chain().units[1].counters.resets, 1u);
  EXPECT_FALSE(lost.controller_reset);  // unit 2 did not reset
  const Reply again = call(2, "XP?");
  EXPECT_EQ(again.status, Reply::Status::ok) << again.text;
  EXPECT_FALSE(again.controller_reset);
  EXPECT_EQ(selections() - sel, 1u);
  // Unit 1 is set up again on its next contact, whose reply reports the reset (issue 49: the
  // commands it ran are lost), once.
  wire_.clear();
  const Reply reset = call(1, "XP?");
  EXPECT_EQ(reset.status, Reply::Status::ok);
  EXPECT_TRUE(reset.controller_reset);
  EXPECT_FALSE(call(1, "XP?").controller_reset);
  EXPECT_NE(wire_.find("M1\\-"), std::string::npos) << wire_;
  EXPECT_NE(log().find("unit 1 reset (unsolicited 'U1')"), std::string::npos) << log();
}

TEST_F(FamilyOnChain, ResetBeforeACommandCannotMisdirectIt) {
  start({0, 1, 2});
  ASSERT_EQ(call(2, "XP?").status, Reply::Status::ok);
  chain_->control("reset", std::vector<std::string>{"1"}, sim::SimClock::now());
  // The command re-selects after the leading CR, so the reset unit passes it on to unit 2.
  const Reply r = command(2, "X=0FA000H");
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  const auto now = sim::SimClock::now();
  EXPECT_TRUE(chain_->unit_at(2).moving('X', now));
  EXPECT_FALSE(chain_->unit_at(1).moving('X', now));
}

TEST_F(FamilyOnChain, KillGoesToTheFirstUnitAndStopsTheChain) {
  start({0, 1, 2});
  for (int unit : {0, 1, 2}) ASSERT_EQ(command(unit, "X++1000").status, Reply::Status::ok);
  wire_.clear();
  const Reply r = call(2, "K", Request::Expect::ack, true);
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(wire_, "\r.U0\rK\rM?\r");
  const auto now = sim::SimClock::now();
  for (std::size_t p = 0; p < 3; ++p) EXPECT_FALSE(chain_->unit_at(p).moving('X', now)) << p;
}

TEST_F(FamilyOnChain, KillFallsBackToEveryUnitWhenTheFirstIsSilent) {
  start({0, 1, 2});
  for (int unit : {1, 2}) ASSERT_EQ(command(unit, "X++1000").status, Reply::Status::ok);
  chain_->control("unit-off", std::vector<std::string>{"0"}, sim::SimClock::now());
  const Reply r = call(1, "K", Request::Expect::ack, true);
  EXPECT_NE(r.status, Reply::Status::ok) << "nothing reaches units behind an unpowered unit";
  EXPECT_NE(log().find("kill: unit 0 did not confirm"), std::string::npos) << log();
}

TEST_F(FamilyOnChain, QueueWarningBlocksMovesUntilQueueEmpty) {
  start({0, 3}, {}, {"0", "3"});
  ASSERT_EQ(call(3, "M?").status, Reply::Status::ok);
  chain_->control("emit", std::vector<std::string>{"3", "Q*"}, sim::SimClock::now());
  EXPECT_EQ(call(3, "XP?").status, Reply::Status::ok);
  const Reply refused = command(3, "X+100");
  EXPECT_EQ(refused.device_code, cn0170::kQueueFull);
  EXPECT_EQ(call(3, "@counters").values[cn0170::kQueueFullNow], 1);
  chain_->control("emit", std::vector<std::string>{"3", "*Q"}, sim::SimClock::now());
  EXPECT_EQ(call(3, "XP?").status, Reply::Status::ok);
  EXPECT_EQ(command(3, "X+100").status, Reply::Status::ok);
}

TEST_F(FamilyOnChain, ProgramModeUnitIsGuarded) {
  start_with_unit_1_in("M2");
  const Reply r = call(1, "XP?");
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, cn0170::kProgramMode);
  EXPECT_EQ(call(1, "M?").values, std::vector<int64_t>{2});
  EXPECT_TRUE(chain_->unit_at(1).program().empty()) << "nothing was stored";
  EXPECT_EQ(command(1, "M1").status, Reply::Status::ok);
  EXPECT_EQ(call(1, "XP?").status, Reply::Status::ok);
}

// Power-up resumes the last mode. A unit found in Operate Mode (M3) may discard what the host
// sends, and its M? -> M3 would confirm commands it never ran: first contact switches it to M1
// and says so.
TEST_F(FamilyOnChain, UnitFoundInOperateModeIsSwitchedToImmediateMode) {
  start_with_unit_1_in("M3");
  wire_.clear();
  const Reply r = command(1, "X+100");
  ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(wire_.substr(0, wire_.find("X+100")),
            "\r.U1\rM?\r\r.U1\rM1\rM?\r\r.U1\rM1\\-\rM?\r\r.U1\r");
  EXPECT_EQ(chain_->unit_at(1).mode(), 1);
  EXPECT_NE(log().find("5 centent-cn0170 chain: unit 1 was in Operate Mode (M3) at "
                       "first contact"),
            std::string::npos)
      << log();
  // Put back in M3 on purpose (run_program), it gets no motor command until M1.
  EXPECT_EQ(command(1, "M3").status, Reply::Status::ok);
  const Reply refused = command(1, "X+100");
  EXPECT_EQ(refused.status, Reply::Status::device_error);
  EXPECT_EQ(refused.device_code, cn0170::kOperateMode);
  EXPECT_EQ(call(1, "M?").values, std::vector<int64_t>{3});
  EXPECT_EQ(command(1, "M1").status, Reply::Status::ok);
  EXPECT_EQ(command(1, "X+100").status, Reply::Status::ok);
}

// --- Proof of alignment (drivers/alignment_proof.hpp) ---------------------------------------

AlignmentResult prove(asio::io_context& io, Link& link, CententFamily& family,
                      const NodeAddress& node, const LinkTiming& timing) {
  const auto proof = family.alignment_proof(family.context_of(node), timing);
  EXPECT_TRUE(proof);
  if (!proof) return {};
  return test::run(io, prove_alignment(link, *proof, timing, timing.byte_timeout, 3));
}

TEST_F(FamilyOnChain, AlignmentProofNamesTheStringsItSent) {
  start({0, 1});
  for (int unit : {0, 1}) {
    const auto result = prove(io_, *link_, family_, nodes_.at(unit), timing_);
    EXPECT_TRUE(result.proved) << result.why;
    EXPECT_EQ(result.attempts, 1);
    EXPECT_TRUE(result.strays.empty());
  }
  // The proof selected the unit itself: the next request selects it again.
  wire_.clear();
  EXPECT_EQ(call(0, "XP?").status, Reply::Status::ok);
  EXPECT_NE(wire_.find(".U0\r"), std::string::npos) << wire_;
}

// A late reply still in the line after the quiet guard is drained ahead of the first answer.
TEST_F(FamilyOnChain, AlignmentProofDrainsALateReply) {
  start({0, 1});
  chain_->control("emit", std::vector<std::string>{"1", "X=00000400h"}, sim::SimClock::now());
  const auto result = prove(io_, *link_, family_, nodes_.at(1), timing_);
  EXPECT_TRUE(result.proved) << result.why;
  EXPECT_EQ(result.strays.size(), 1u);
}

// A late line equal to the first answer is taken for it; the second step then reads the real
// first answer, fails, and the proof goes on until the answers come in step.
TEST_F(FamilyOnChain, AlignmentProofIsNotFooledByALateCopyOfItsAnswer) {
  start({0, 1});
  chain_->control("emit", std::vector<std::string>{"1", "\"XY?\" ?"}, sim::SimClock::now());
  const auto result = prove(io_, *link_, family_, nodes_.at(1), timing_);
  EXPECT_TRUE(result.proved) << result.why;
  EXPECT_EQ(result.attempts, 2);
}

TEST_F(FamilyOnChain, GarbageAndSilenceGivePreciseStatuses) {
  start({0, 1});
  ASSERT_EQ(call(1, "XP?").status, Reply::Status::ok);
  chain_->control("emit", std::vector<std::string>{"1", "#$%&"}, sim::SimClock::now());
  const Reply garbled = call(1, "XP?");
  EXPECT_EQ(garbled.status, Reply::Status::garbled);
  EXPECT_NE(garbled.text.find("unreadable line"), std::string::npos) << garbled.text;
  EXPECT_EQ(call(1, "XP?").status, Reply::Status::ok);
  chain_->control("unit-off", std::vector<std::string>{"1"}, sim::SimClock::now());
  EXPECT_EQ(call(1, "XP?").status, Reply::Status::timeout);
  EXPECT_EQ(call(0, "XP?").status, Reply::Status::ok);
}

TEST_F(FamilyOnChain, SettingRewritesReachTheUnit) {
  start({0, 1});
  EXPECT_EQ(command(1, "XC17;XH1;XR125").status, Reply::Status::ok);
  EXPECT_EQ(call(1, "XC?").values, std::vector<int64_t>{17});
  EXPECT_TRUE(chain_->unit_at(1).axis('X').home_cw);
  EXPECT_EQ(command(1, "XR3").device_code, cn0170::kInvalidValue);
  EXPECT_EQ(command(1, "XP=0400H;X+0FFFFFC00H").status, Reply::Status::ok);
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(call(1, "XP?").values[0], 0);
}

TEST(CententFamilyModel, ValidateModelCatchesMistakes) {
  CententFamily family;
  Model m;
  m.name = "bad";
  m.options = {{"overflow_mode", "loud"}};
  const auto point = [&](const char* name, const char* read, NumberFormat f, int field = 0) {
    PointDef p;
    p.name = name;
    std::string error;
    p.read = ReadSpec{*CommandTemplate::compile(read, error), field, f, std::nullopt};
    m.points.push_back(p);
  };
  point("a", "XP?;YP?", NumberFormat::decimal);
  point("b", "P1?;XP?", NumberFormat::hex);
  point("c", "XP?", NumberFormat::hex, 3);
  point("d", "XQ?", NumberFormat::decimal);
  point("e", "@count", NumberFormat::decimal);
  point("f", "@counters", NumberFormat::decimal, 11);
  point("g", "XP?;YP?", NumberFormat::decimal, 4);  // the motion word: either format
  point("h", "P1?;XP?", NumberFormat::hex, 1);
  ActionDef a;
  a.name = "stop_all";
  a.bus_wide = false;
  ActionStep s;
  std::string error;
  s.command = *CommandTemplate::compile("K", error);
  a.steps.push_back(s);
  s.command = *CommandTemplate::compile(".U2;M2", error);
  a.steps.push_back(s);
  m.actions.push_back(a);
  Diagnostics d;
  family.validate_model(m, d);
  const std::string text = d.to_text();
  for (const char* expected :
       {"option overflow_mode: expected warning, rts or leave, found 'loud'",
        "point a read: field 0 of 'XP?;YP?' is a hex reply (lower-case h suffix): add format: hex",
        "point b read: field 0 of 'P1?;XP?' is not a hex reply; remove format: hex",
        "point c read: 'XP?' yields fields 0..2, not 3",
        "point d read: 'XQ?' is not a CN0170 query",
        "point e read: unknown gateway-local read '@count'",
        "action stop_all: K is relayed down the whole chain (p.13): put it in an action with "
        "bus_wide: true",
        "action stop_all: '.U2': the family selects units itself",
        "action stop_all: M2 from Immediate Mode erases the stored program"})
    EXPECT_NE(text.find(expected), std::string::npos) << expected << "\n" << text;
  for (const char* fine : {"point f", "point g", "point h"})
    EXPECT_EQ(text.find(fine), std::string::npos) << text;
}

}  // namespace
}  // namespace fieldgate

// --- the core read+move scenario under every reading of the manual (issue 20) ----------------

namespace fieldgate {
namespace {

struct CententReading {
  const char* name;
  const char* separator;  // after the unit digit
  bool xp;                // XP=…h (p.2) instead of X=…h (p.35)
  const char* terminator;
  bool prefix_unit_messages;
  bool plain_overflow;  // the units take M1- only
};

std::ostream& operator<<(std::ostream& os, const CententReading& r) {
  return os << r.name;
}

const CententReading kCententReadings[] = {
    {"digit_x_cr", "", false, "\r", false, false},
    {"space_xp_crlf", " ", true, "\r\n", true, false},
    {"colon_x_lf", ":", false, "\n", false, true},
    {"digit_xp_crlf_prefixed_unit_messages", "", true, "\r\n", true, true},
};

class CententEveryReading : public FamilyOnChain,
                            public ::testing::WithParamInterface<CententReading> {};

TEST_P(CententEveryReading, PowerUpReadMoveReadBack) {
  const CententReading& reading = GetParam();
  sim::centent::ChainOptions o;
  o.power_up = true;  // as the units power up: waiting for the auto-baud CR
  o.prefix_separator = reading.separator;
  o.unit.position_reply_xp = reading.xp;
  o.terminator = reading.terminator;
  o.prefix_unit_messages = reading.prefix_unit_messages;
  o.unit.accept_backslash_overflow = !reading.plain_overflow;
  start({0, 1, 2}, o);
  EXPECT_NE(log().find("auto-baud CR answered by unit(s) 0, 1, 2"), std::string::npos) << log();
  EXPECT_NE(log().find("chain order from .U?: 0, 1, 2"), std::string::npos) << log();
  for (int unit : {0, 1, 2}) {
    const Reply r = call(unit, "XP?;YP?");
    ASSERT_EQ(r.status, Reply::Status::ok) << unit << ": " << r.text;
    EXPECT_EQ(r.values, (std::vector<int64_t>{0, 0, 0, 0, 0}));
  }
  const Reply move = command(2, "XV=200,4000;XA=0FFH;X=0FA000H");
  ASSERT_EQ(move.status, Reply::Status::ok) << move.text;
  Reply r;
  for (int i = 0; i < 200; ++i) {
    r = call(2, "XP?;YP?");
    ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
    if ((r.values[4] & cn0170::kMoving) == 0) break;
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_EQ(r.values[0], 1000 * 1024);
  EXPECT_EQ(r.values[4], 0);
  EXPECT_EQ(call(1, "XP?;YP?").values[0], 0) << "unit 1 never moved";
  EXPECT_EQ(call(0, "M?").values, std::vector<int64_t>{1});
}

INSTANTIATE_TEST_SUITE_P(Readings, CententEveryReading, ::testing::ValuesIn(kCententReadings),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate

// Replies slower than the reply timeout (issue 12): every value taken as good is that unit's,
// every command confirmed ran on that unit.
namespace fieldgate {
namespace {

TEST_F(FamilyOnChain, LateRepliesNeverAnswerAnotherRequest) {
  start({0, 1, 2});
  const std::map<int, int64_t> positions{{0, 1000 * 1024}, {1, 2500 * 1024}, {2, 77 * 1024}};
  for (const auto& [unit, p] : positions) {
    ASSERT_EQ(command(unit, fmt::format("XP=0{:X}H", p)).status, Reply::Status::ok);
    ASSERT_EQ(call(unit, "XP?;YP?").values.front(), p);
  }
  // A command whose confirmation is late, then one the unit rejects: the late M1 is the first's.
  reply_delay_ = 60ms;
  EXPECT_EQ(command(1, "P3=1").status, Reply::Status::timeout);
  reply_delay_ = 0ms;
  const Reply rejected = command(1, "XZ=5");
  EXPECT_NE(rejected.status, Reply::Status::ok) << "confirmed by the late M1 of P3=1";
  std::this_thread::sleep_for(100ms);
  io_.poll();

  std::mt19937 random(5);
  const std::chrono::milliseconds delays[] = {0ms, 10ms, 20ms, 40ms, 60ms, 100ms};
  int good = 0, refused = 0, confirmed = 0;
  for (int i = 0; i < 150; ++i) {
    reply_delay_ = delays[random() % std::size(delays)];
    const int unit = static_cast<int>(random() % 3);
    if (random() % 5 == 0) {
      // The unit rejects it ("…" ?): never confirmed, whatever late M1 is on its way.
      const Reply r = command(unit, "XZ=5");
      EXPECT_NE(r.status, Reply::Status::ok) << "a rejected command confirmed on unit " << unit;
      continue;
    }
    if (random() % 4 == 0) {
      const bool on = random() % 2;
      const Reply r = command(unit, on ? "P3=1" : "P3=0");
      if (r.status == Reply::Status::ok) {
        ++confirmed;
        EXPECT_EQ(chain_->find(unit)->output(3), on) << "command to unit " << unit;
      }
      continue;
    }
    const Reply r = call(unit, "XP?;YP?");
    if (r.status != Reply::Status::ok) {
      ++refused;
      continue;
    }
    ++good;
    EXPECT_EQ(r.values.front(), positions.at(unit)) << "read of unit " << unit;
  }
  reply_delay_ = 0ms;
  std::this_thread::sleep_for(400ms);
  io_.poll();
  for (const auto& [unit, p] : positions) {
    Reply r = call(unit, "XP?;YP?");
    if (r.status != Reply::Status::ok) r = call(unit, "XP?;YP?");
    EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
    EXPECT_EQ(r.values.front(), p);
  }
  std::cout << "[ measured ] " << good << " good reads, " << refused << " refused, " << confirmed
            << " commands confirmed, " << family_.chain().late_replies << " late replies skipped\n";
  EXPECT_GT(good, 0);
  EXPECT_GT(refused, 0);
  EXPECT_GT(family_.chain().late_replies, 0u);
}

}  // namespace
}  // namespace fieldgate

// §9 #6 and #9: whether a unit selects itself after power-up, and whether units a K passes obey
// it. The kill stops the chain under every combination.
namespace fieldgate {
namespace {

class CententKillReadings : public FamilyOnChain,
                            public ::testing::WithParamInterface<std::pair<bool, bool>> {};

TEST_P(CententKillReadings, KillStopsEveryUnit) {
  sim::centent::ChainOptions o;
  o.power_up = true;
  o.select_self_after_reset = GetParam().first;
  o.kill_acts_upstream = GetParam().second;
  start({0, 1, 2}, o);
  for (int unit : {0, 1, 2}) ASSERT_EQ(command(unit, "X++1000").status, Reply::Status::ok);
  const Reply r = call(1, "K", Request::Expect::ack, true);
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  const auto now = sim::SimClock::now();
  for (std::size_t p = 0; p < 3; ++p) EXPECT_FALSE(chain_->unit_at(p).moving('X', now)) << p;
}

INSTANTIATE_TEST_SUITE_P(Readings, CententKillReadings,
                         ::testing::Values(std::pair{true, false}, std::pair{false, false},
                                           std::pair{true, true}, std::pair{false, true}));

}  // namespace
}  // namespace fieldgate
