// The family's decisions on complete transcripts (pure), then whole transactions through a Link
// against the simulated party line in process.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

#include <chrono>
#include <deque>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <utility>

#include "drivers/ims_party_line/ims_chain.hpp"
#include "drivers/ims_party_line/ims_codec.hpp"
#include "drivers/ims_party_line/ims_family.hpp"
#include "tests/families/ims_party_line/ims_chain_bench.hpp"
#include "tests/harness/address_checks.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

using test::read;
using test::unit;
using test::write;
Request global(const char* c) {
  return {c, Request::Expect::ack, NumberFormat::decimal, true};
}

// --- pure interpretation of transcripts (§2 byte-level examples) -----------------------------

TEST(ImsInterpret, PositionWithAndWithoutTheNameInTheEcho) {
  for (const char* received : {"AZ\n   1000\r\n", "Z\n   1000\r\n"}) {
    const Reply r = interpret_ims_reply(unit('A'), read("Z"), received);
    EXPECT_EQ(r.status, Reply::Status::ok) << received << ": " << r.text;
    EXPECT_EQ(r.values, std::vector<int64_t>{1000});
  }
}

TEST(ImsInterpret, StatusAndIo) {
  Reply r = interpret_ims_reply(unit('A'), read("^"), "A^\n  9\r\n");
  ASSERT_EQ(r.status, Reply::Status::ok);
  EXPECT_EQ(r.values, std::vector<int64_t>{9});
  // The name equals the command character: both echo forms still match.
  for (const char* received : {"AA129\n  40\r\n", "A129\n  40\r\n"}) {
    r = interpret_ims_reply(unit('A'), read("A129"), received);
    EXPECT_EQ(r.status, Reply::Status::ok) << received;
    EXPECT_EQ(r.values, std::vector<int64_t>{40});
  }
}

TEST(ImsInterpret, CommandsAreAcknowledgedByTheirEcho) {
  for (const char* received : {"X+1000\n", "+1000\n", "X+1000\n\r\n", "+1000\n\r\n"})
    EXPECT_EQ(interpret_ims_reply(unit('X'), write("+1000"), received).status, Reply::Status::ok)
        << received;
  EXPECT_EQ(interpret_ims_reply(unit('B'), write("R-200.25"), "BR-200.25\n").status,
            Reply::Status::ok);
}

TEST(ImsInterpret, LateCompletionsAreSkipped) {
  // The CR LF of an earlier (queued) command may come before the echo or the result.
  EXPECT_EQ(interpret_ims_reply(unit('A'), read("Z"), "\r\nAZ\n   5\r\n").values,
            std::vector<int64_t>{5});
  EXPECT_EQ(interpret_ims_reply(unit('A'), read("Z"), "AZ\n\r\n   5\r\n").values,
            std::vector<int64_t>{5});
}

TEST(ImsInterpret, SilenceIsATimeout) {
  const Reply r = interpret_ims_reply(unit('D'), read("Z"), "");
  EXPECT_EQ(r.status, Reply::Status::timeout);
  EXPECT_EQ(r.text, "no echo from unit D");
}

TEST(ImsInterpret, BadEchoesAreGarbled) {
  struct Case {
    const char* received;
    const char* text;
  };
  const Case cases[] = {
      {"AZ", "incomplete echo 'AZ'"},
      {"BZ\n   1000\r\n", "echo 'BZ\\n' does not match 'AZ\\n'"},
      {"A\xda\n", "does not match"},
      {"AZ\n", "echoed 'Z' but sent no result line"},
      {"AZ\n   10", "incomplete result line '   10'"},
      {"AZ\n\"32.\r\n", "is no result line"},
  };
  for (const auto& c : cases) {
    const Reply r = interpret_ims_reply(unit('A'), read("Z"), c.received);
    EXPECT_EQ(r.status, Reply::Status::garbled) << c.received;
    EXPECT_NE(r.text.find(c.text), std::string::npos) << r.text;
  }
}

TEST(ImsFamily, AddressesAreNames) {
  ImsPartyLineFamily f;
  ASSERT_TRUE(test::expect_address(f, "B", "B", 'B'));
  std::string error;
  EXPECT_TRUE(f.parse_address("_", error));
  for (const char* bad : {"", "AB", "1", "@", "*", " "}) {
    EXPECT_FALSE(f.parse_address(bad, error)) << bad;
    EXPECT_FALSE(error.empty());
  }
}

TEST(ImsFamily, WireEstimate) {
  ImsPartyLineFamily f;
  // "AZ\n" out, "AZ\n" back at most, "   1000\r\n".
  EXPECT_EQ(f.estimate_wire_chars(unit('A'), read("Z")), 16u);
  EXPECT_EQ(f.estimate_wire_chars(unit('A'), write("V2000")), 16u);
  EXPECT_EQ(f.estimate_wire_chars(unit('A'), global("\x1b")), 1u);
}

// --- transactions against the simulated chain -------------------------------------------------

class ImsTransact : public ::testing::Test, protected test::ImsChainBench {
 protected:
  ImsTransact() : ImsChainBench(LinkTiming{20ms, 5ms}) {}
  void SetUp() override { make_chain({}); }

  void make_chain(sim::ims::PartyLineOptions options) {
    if (options.names.size() == 1 && options.names.front() == 'A') options.names = {'A', 'B', 'C'};
    attach(std::move(options));
  }

  // The `^` value, -1 if the read failed.
  int64_t status_of(char name) {
    const Reply r = transact(name, read("^"));
    return r.status == Reply::Status::ok && !r.values.empty() ? r.values.front() : -1;
  }
};

TEST_F(ImsTransact, ReadsEveryAxisOnTheChain) {
  expect_each_axis_reads_its_position();
  EXPECT_EQ(transact('A', read("^")).values, std::vector<int64_t>{0});
  EXPECT_EQ(transport_->writes().back(), "A^\n");
}

TEST_F(ImsTransact, NameEchoAndMissingCompletionAreBothFine) {
  sim::ims::PartyLineOptions options;
  options.echo_name = true;
  options.completion = false;
  make_chain(options);
  EXPECT_EQ(transact('A', write("V2000")).status, Reply::Status::ok);
  const Reply r = transact('A', read("Z"));
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
}

TEST_F(ImsTransact, MissingNameTimesOutAfterTheReplyTimeout) {
  const auto start = std::chrono::steady_clock::now();
  const Reply r = transact('D', read("Z"));
  const auto took = std::chrono::steady_clock::now() - start;
  EXPECT_EQ(r.status, Reply::Status::timeout);
  EXPECT_GE(took, timing_.reply_timeout);
  EXPECT_LT(took, timing_.reply_timeout + 250ms);
  EXPECT_EQ(transact('A', read("Z")).status, Reply::Status::ok);
}

TEST_F(ImsTransact, GarbledAndTruncatedEchoesThenResynchronise) {
  transport_->faults().garbage_replies = 1;
  Reply r = transact('B', read("Z"));
  EXPECT_EQ(r.status, Reply::Status::garbled) << r.text;
  EXPECT_EQ(transact('B', read("Z")).status, Reply::Status::ok);
  transport_->faults().truncated_replies = 1;
  r = transact('C', read("^"));
  EXPECT_EQ(r.status, Reply::Status::garbled);
  EXPECT_NE(r.text.find("incomplete echo"), std::string::npos) << r.text;
  // C's result may still come: until the late window has passed, no result on a line of its own
  // is taken (README "Late replies"), an echo-confirmed write is.
  r = transact('A', read("Z"));
  EXPECT_EQ(r.status, Reply::Status::garbled);
  EXPECT_NE(r.text.find("late answer"), std::string::npos) << r.text;
  EXPECT_EQ(transact('A', write("A8")).status, Reply::Status::ok);
  std::this_thread::sleep_for(ImsPartyLineFamily::late_window(timing_));
  for (char name : {'A', 'B', 'C'}) EXPECT_EQ(transact(name, read("Z")).status, Reply::Status::ok);
}

// --- Proof of alignment (drivers/alignment_proof.hpp) ---------------------------------------

AlignmentResult prove(asio::io_context& io, Link& link, ImsPartyLineFamily& family, char name,
                      const LinkTiming& timing) {
  const auto proof = family.alignment_proof(family.context_of(unit(name)), timing);
  EXPECT_TRUE(proof);
  if (!proof) return {};
  auto future = asio::co_spawn(io, prove_alignment(link, *proof, timing, timing.byte_timeout, 3),
                               asio::use_future);
  io.restart();
  while (future.wait_for(0s) != std::future_status::ready) io.run_one_for(10ms);
  return future.get();
}

TEST_F(ImsTransact, AlignmentProofOnEveryUnit) {
  for (char name : {'A', 'B', 'C'}) {
    const auto result = prove(io_, *link_, family_, name, timing_);
    EXPECT_TRUE(result.proved) << name << ": " << result.why;
    EXPECT_EQ(result.attempts, 1);
    EXPECT_TRUE(result.strays.empty());
  }
  EXPECT_EQ(transport_->writes().back(), "CZ\n");
  // An absent unit proves nothing.
  EXPECT_FALSE(prove(io_, *link_, family_, 'D', timing_).proved);
}

// Canned bytes, one answer per write (the writes beyond them get silence).
class ScriptedLine final : public test::FakeLine {
 public:
  ScriptedLine(asio::io_context& io, std::deque<std::string> answers)
      : FakeLine(io, "scripted party line", 1e6 * 10 / 9600) {
    set_far_end([this, answers = std::move(answers)](std::string_view) mutable {
      if (answers.empty()) return;
      deliver(answers.front());
      answers.pop_front();
    });
  }
};

// A late reply still in the line after the guard is drained ahead of the first answer; a late
// `^` reply taken for the first answer leaves the real one to the second step, whose echo must
// be `Z`: it fails, and the next attempt comes in step.
TEST(ImsAlignmentProof, LateRepliesAreDrainedOrMakeAStepFail) {
  const LinkTiming timing{20ms, 5ms};
  {
    asio::io_context io;
    ScriptedLine line(io, {"AZ\n   1000\r\nA^\n  0\r\n", "AZ\n   1000\r\n"});
    Link link(line);
    ImsPartyLineFamily family;
    const auto result = prove(io, link, family, 'A', timing);
    EXPECT_TRUE(result.proved) << result.why;
    // The late Z reply, echo and result line, each a stray.
    EXPECT_EQ(result.strays, (std::vector<std::string>{"AZ\n", "   1000\r\n"}));
  }
  {
    asio::io_context io;
    ScriptedLine line(
        // The second attempt runs the steps in reverse order (Z, then ^).
        io, {"A^\n  1\r\nA^\n  0\r\n", "AZ\n   1000\r\n", "AZ\n   1000\r\n", "A^\n  0\r\n"});
    Link link(line);
    ImsPartyLineFamily family;
    const auto result = prove(io, link, family, 'A', timing);
    EXPECT_TRUE(result.proved) << result.why;
    EXPECT_EQ(result.attempts, 2);
  }
}

// A unit in Single mode (its Party input not grounded at reset) echoes every character of
// `A^\n` but the LF, which is no terminator there, and executes nothing. The family says so
// instead of only reporting garbled replies; no command switches the mode.
TEST(ImsSingleMode, TheUnitIsNamedAsInSingleMode) {
  EXPECT_TRUE(ims::single_mode_echo('A', "^", "A^"));
  EXPECT_TRUE(ims::single_mode_echo('A', "^", "A"));  // after a reset: the name, until a Space
  EXPECT_FALSE(ims::single_mode_echo('A', "^", "^"));
  EXPECT_FALSE(ims::single_mode_echo('A', "Z", "A^"));
  const LinkTiming timing{20ms, 5ms};
  asio::io_context io;
  ScriptedLine line(io, {"A^", "A^", "AZ", "A^\n  0\r\n"});
  Link link(line);
  ImsPartyLineFamily family;
  std::vector<std::string> logged;  // warnings
  const auto exchange = [&](const char* command) {
    const Request request = read(command);  // outlives the coroutine, which holds a reference
    const NodeAddress node = unit('A');
    auto future =
        asio::co_spawn(io, family.transact(link, node, request, timing), asio::use_future);
    io.restart();
    while (future.wait_for(0s) != std::future_status::ready) io.run_one_for(10ms);
    for (auto& note : link.take_notes())
      if (note.level <= 4) logged.push_back(std::move(note.text));
    return future.get();
  };
  Reply r = exchange("^");
  EXPECT_EQ(r.status, Reply::Status::garbled);
  EXPECT_EQ(r.text.find("Single mode"), std::string::npos) << "once may be a cut line";
  r = exchange("^");
  EXPECT_EQ(r.status, Reply::Status::garbled);
  EXPECT_NE(r.text.find("unit A answers as an indexer in Single mode"), std::string::npos)
      << r.text;
  EXPECT_NE(r.text.find("ground the Party input"), std::string::npos) << r.text;
  r = exchange("Z");
  EXPECT_NE(r.text.find("3 times in a row"), std::string::npos) << r.text;
  ASSERT_EQ(logged.size(), 1u) << "said once";
  EXPECT_NE(logged[0].find("Single mode"), std::string::npos);
  // A party-line echo ends the streak (once the results the cut echoes owed are written off).
  std::this_thread::sleep_for(ImsPartyLineFamily::late_window(timing));
  r = exchange("^");
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
}

TEST_F(ImsTransact, DuplicateNameGarblesOnlyThatName) {
  control("duplicate", {"B", "on"});
  EXPECT_EQ(transact('B', read("Z")).status, Reply::Status::garbled);
  EXPECT_EQ(transact('A', read("Z")).status, Reply::Status::ok);
  control("duplicate", {"B", "off"});
  EXPECT_EQ(transact('B', read("Z")).status, Reply::Status::ok);
}

TEST_F(ImsTransact, MovesAndTheMotionGuard) {
  ASSERT_EQ(transact('A', write("V5000")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("K0 0")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', read("^")).values, std::vector<int64_t>{0});
  ASSERT_EQ(transact('A', write("R2000")).status, Reply::Status::ok);
  EXPECT_EQ(status_of('A') & 1, 1);
  // A second index would queue and stall the unit: refused before it reaches the wire.
  transport_->clear_writes();
  const Reply again = transact('A', write("R0"));
  EXPECT_EQ(again.status, Reply::Status::device_error);
  EXPECT_EQ(again.device_code, static_cast<int64_t>(ims::Refusal::axis_moving));
  EXPECT_TRUE(transport_->writes().empty());
  std::this_thread::sleep_for(450ms);
  EXPECT_EQ(transact('A', read("^")).values, std::vector<int64_t>{0});
  EXPECT_EQ(transact('A', read("Z")).values, std::vector<int64_t>{2000});
  EXPECT_EQ(transact('A', write("R0")).status, Reply::Status::ok);
}

// A move aborts a jog (axis profile, buffer mode Aborting): an index for a jogging unit ramps the
// jog down with M0, reads `^` until the unit is idle, and then goes out.
TEST_F(ImsTransact, AnIndexForAJoggingUnitEndsTheJogFirst) {
  ASSERT_EQ(transact('A', write("V2000")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("K50 50")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("M3000")).status, Reply::Status::ok);
  std::this_thread::sleep_for(200ms);  // past the 0.12 s ramp
  ASSERT_NE(transact('A', read("^")).values.at(0) & 1, 0);
  transport_->clear_writes();
  const Reply moved = transact('A', write("R0"));
  ASSERT_EQ(moved.status, Reply::Status::ok) << moved.text;
  const auto writes = transport_->writes();
  ASSERT_GE(writes.size(), 3u);
  EXPECT_EQ(writes.front(), "AM0\n");
  EXPECT_EQ(writes[writes.size() - 2], "A^\n");  // the last status read showed it idle
  EXPECT_EQ(writes.back(), "AR0\n");
  EXPECT_NE(status_of('A') & 1, 0);  // the index runs
  // An index for a unit that runs an index is still refused: that is not a jog.
  const Reply again = transact('A', write("R100"));
  EXPECT_EQ(again.device_code, static_cast<int64_t>(ims::Refusal::axis_moving));
}

TEST_F(ImsTransact, LateCompletionOfAQueuedIndexDoesNotDisturbPolls) {
  // Without status polls the guard is off, so the second index queues in the unit (§6): its
  // CR LF comes when the first move ends, in the middle of later exchanges.
  ASSERT_EQ(transact('A', write("V4000")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("K0 0")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("R400")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("R0")).status, Reply::Status::ok);
  const auto until = std::chrono::steady_clock::now() + 400ms;
  int polls = 0;
  while (std::chrono::steady_clock::now() < until) {
    const Reply r = transact(polls % 2 ? 'B' : 'A', read("Z"));
    ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
    ++polls;
  }
  EXPECT_GT(polls, 10);
  EXPECT_EQ(transact('A', read("Z")).values, std::vector<int64_t>{0});
}

TEST_F(ImsTransact, FastAxisPacesEveryLineCharacterByCharacter) {
  ASSERT_EQ(transact('A', write("K0 0")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("M15000")).status, Reply::Status::ok);
  ASSERT_TRUE(family_.shadow().fast());
  // The simulated unit overruns on characters that arrive back to back while it steps faster
  // than 10,000 steps/s: paced lines get through.
  transport_->clear_writes();
  for (int i = 0; i < 5; ++i) {
    const Reply r = transact('A', read("Z"));
    EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  }
  const Reply b = transact('B', read("Z"));
  EXPECT_EQ(b.status, Reply::Status::ok) << b.text;
  for (const auto& w : transport_->writes()) EXPECT_EQ(w.size(), 1u) << w;
  ASSERT_EQ(transact('A', write("M0")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', read("^")).values, std::vector<int64_t>{0});
  EXPECT_FALSE(family_.shadow().fast());
  transport_->clear_writes();
  EXPECT_EQ(transact('A', read("Z")).status, Reply::Status::ok);
  EXPECT_EQ(transport_->writes(), std::vector<std::string>{"AZ\n"});
}

TEST_F(ImsTransact, PacedLinesToAnEchoingNameWork) {
  sim::ims::PartyLineOptions options;
  options.echo_name = true;
  make_chain(options);
  ASSERT_EQ(transact('A', write("K0 0")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("M-15000")).status, Reply::Status::ok);
  const Reply r = transact('A', read("A129"));  // name and command character are the same
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(transact('D', read("Z")).status, Reply::Status::timeout);
  EXPECT_EQ(transact('C', read("Z")).status, Reply::Status::ok);
}

TEST_F(ImsTransact, WithoutPacingAFastUnitOverruns) {
  // What pacing prevents: the whole line at once to a unit stepping at 15,000 steps/s.
  ASSERT_EQ(transact('A', write("K0 0")).status, Reply::Status::ok);
  ASSERT_EQ(transact('A', write("M15000")).status, Reply::Status::ok);
  std::string out = chain().echo("AZ\n");
  EXPECT_EQ(out, "Z") << "the unit lost the rest of the line";
  EXPECT_TRUE(chain().respond("AZ\n", sim::SimClock::now()).bytes.empty());
}

TEST_F(ImsTransact, BusWideCommandsGoOutWithoutAName) {
  for (char name : {'A', 'B', 'C'}) {
    ASSERT_EQ(transact(name, write("K0 0")).status, Reply::Status::ok);
    ASSERT_EQ(transact(name, write("M1000")).status, Reply::Status::ok);
  }
  transport_->clear_writes();
  Reply r = transact('C', global("M0"));  // firmware 1.15 `*`: every unit echoes at once
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(transport_->writes(), std::vector<std::string>{"*M0\n"});
  std::this_thread::sleep_for(50ms);
  for (char name : {'A', 'B', 'C'}) EXPECT_EQ(status_of(name), 0) << name;

  for (char name : {'A', 'B'}) ASSERT_EQ(transact(name, write("M1000")).status, Reply::Status::ok);
  transport_->clear_writes();
  EXPECT_EQ(transact('A', global("@")).status, Reply::Status::ok);
  EXPECT_EQ(transport_->writes(), std::vector<std::string>{"@\n"});
  std::this_thread::sleep_for(20ms);
  for (char name : {'A', 'B'}) EXPECT_EQ(status_of(name), 0) << name;

  for (char name : {'A', 'B'}) ASSERT_EQ(transact(name, write("M1000")).status, Reply::Status::ok);
  transport_->clear_writes();
  EXPECT_EQ(transact('B', global("\x1b")).status, Reply::Status::ok);
  EXPECT_EQ(transport_->writes(), std::vector<std::string>{"\x1b"});
  for (char name : {'A', 'B'}) EXPECT_EQ(status_of(name), 0) << name;

  control("position", {"B", "1234"});
  EXPECT_EQ(transact('B', global("\x03")).status, Reply::Status::ok);
  EXPECT_EQ(transact('B', read("Z")).values, std::vector<int64_t>{0}) << "reset zeroes the origin";
  const Request bus_wide_read{"Z", Request::Expect::values, NumberFormat::decimal, true};
  EXPECT_EQ(transact('B', bus_wide_read).status, Reply::Status::device_error)
      << "a read cannot be bus-wide";
}

TEST_F(ImsTransact, UrgentStopGoesOutAtOnce) {
  ASSERT_EQ(transact('A', write("M1000")).status, Reply::Status::ok);
  transport_->clear_writes();
  Reply r = run(family_.send_urgent(*link_, unit('A'), global("\x1b")));
  EXPECT_EQ(r.status, Reply::Status::ok);
  EXPECT_EQ(transport_->writes(), std::vector<std::string>{"\x1b"});
  EXPECT_EQ(transact('A', read("^")).values, std::vector<int64_t>{0});
  r = run(family_.send_urgent(*link_, unit('A'), write("M0")));
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, static_cast<int64_t>(ims::Refusal::not_global));
  r = run(family_.send_urgent(*link_, unit('A'), global("M0")));
  EXPECT_EQ(r.status, Reply::Status::device_error) << "only ESC, ^C and @ are urgent";
}

TEST_F(ImsTransact, CommandsWithoutEchoDoNotHang) {
  Reply r = transact('A', write("X"));  // answers '"32.' in party mode
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  r = transact('A', read("X"));
  EXPECT_EQ(r.status, Reply::Status::garbled);
  EXPECT_EQ(transact('A', read("Z")).status, Reply::Status::ok);
}

TEST_F(ImsTransact, OutputsRuleAndSaveGuardAreEnforcedBeforeTheWire) {
  Reply r = transact('A', write("A12"));
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, static_cast<int64_t>(ims::Refusal::output_value));
  EXPECT_EQ(transact('A', write("A24")).status, Reply::Status::ok);
  EXPECT_EQ(transact('A', read("A129")).values, std::vector<int64_t>{24});
  EXPECT_EQ(transact('A', write("S")).status, Reply::Status::ok);
  r = transact('A', write("S"));
  EXPECT_EQ(r.device_code, static_cast<int64_t>(ims::Refusal::eeprom_rate));
  EXPECT_EQ(chain().unit('A')->eeprom_writes(), 1);
}

TEST_F(ImsTransact, UnitThatWasSwitchedOffComesBack) {
  control("axis-off", {"C"});
  EXPECT_EQ(transact('C', read("Z")).status, Reply::Status::timeout);
  control("axis-on", {"C"});
  EXPECT_EQ(transact('C', read("Z")).status, Reply::Status::ok);
}

// Sending ahead (drivers/README.md): the serial bus asks for the next poll's line while the poll
// before it is on the wire, and writes it once that poll's reply is accepted. Whatever the
// family gives then must be exactly the first line its transact() for that poll sends. Random
// traffic to three units (polls, parameters, indexes, jogs fast and slow, M0), the lines asked
// for as the bus asks for them.
TEST_F(ImsTransact, APollSentAheadIsTheFirstLineItsExchangeSends) {
  const std::vector<const char*> polls = {"Z", "^", "z"};
  const std::vector<const char*> commands = {"V5000", "K0 0", "R200",  "R-200",
                                             "M3000", "M0",   "M15000"};
  std::mt19937 random(20261207);
  int given = 0, withheld = 0;
  std::optional<std::pair<char, std::string>> ahead;  // (unit, line) asked for the next poll
  for (int step = 0; step < 400; ++step) {
    const char name = "ABC"[random() % 3];
    const bool poll = random() % 4 != 0;
    const std::size_t pick = random() % (poll ? polls.size() : commands.size());
    const Request r = poll ? read(polls[pick]) : write(commands[pick]);
    SCOPED_TRACE(::testing::Message() << "step " << step << ": " << name << r.command);
    // The line asked for while the previous poll was on the wire, for this poll.
    const std::optional<std::string> expected =
        ahead && poll && ahead->first == name ? std::optional(ahead->second) : std::nullopt;
    ahead.reset();
    // While this poll is on the wire the bus asks for the line of the poll after it: here, the
    // next step's if it is a poll, drawn now from a copy of the generator.
    if (poll) {
      auto peek = random;
      const char next_name = "ABC"[peek() % 3];
      if (peek() % 4 != 0) {
        const Request next = read(polls[peek() % polls.size()]);
        if (auto line = family_.pipelined_request(family_.context_of(unit(next_name)), next)) {
          ahead.emplace(next_name, *line);
          ++given;
        } else {
          ++withheld;
        }
      }
    }
    transport_->clear_writes();
    const Reply reply = transact(name, r);
    if (expected) {
      ASSERT_FALSE(transport_->writes().empty());
      EXPECT_EQ(transport_->writes().front(), *expected);
    }
    if (reply.status != Reply::Status::ok) ahead.reset();  // the bus sends nothing ahead then
    if (!poll && step % 16 == 0) std::this_thread::sleep_for(50ms);  // let moves end now and then
  }
  RecordProperty("lines_given", given);
  RecordProperty("lines_withheld", withheld);
  EXPECT_GT(given, 60);     // not a vacuous check
  EXPECT_GT(withheld, 10);  // fast steps and jogs were in the traffic
}

}  // namespace
}  // namespace fieldgate
