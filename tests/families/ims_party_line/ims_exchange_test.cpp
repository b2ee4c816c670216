// One exchange's decisions with what the family remembers between exchanges (pins, readings
// seen, replies owed, units gone silent), fed line by line at literal times, with no Link.
#include "drivers/ims_party_line/ims_exchange.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "tests/families/ims_party_line/ims_chain_bench.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using Next = ims::Exchange::Next;

using test::read;
using test::unit;
using test::write;

const ims::Clock::time_point t0{};

// Unit A's memory between exchanges, and exchanges with it (or with B) over that memory.
class ImsExchange : public ::testing::Test {
 protected:
  ims::Exchange start(const Request& request) { return start(a_, request, track_); }
  ims::Exchange start(const NodeAddress& node, const Request& request, ims::UnitTrack& track) {
    return ims::Exchange(node, request, readings_, late_, track, 500ms);
  }

  const NodeAddress a_ = unit('A');
  const NodeAddress b_ = unit('B');
  const Request z_ = read("Z");
  const Request v_ = write("V2000");
  ims::UnitReadings readings_;
  ims::LateReplies late_;
  ims::UnitTrack track_;
};

bool contains(const std::string& text, const char* part) {
  return text.find(part) != std::string::npos;
}

TEST_F(ImsExchange, AQueryReadsItsResultOnTheNextLineAndLogsTheReadingsItFound) {
  ims::Exchange x = start(z_);
  EXPECT_EQ(x.next(), Next::echo);
  EXPECT_EQ(x.on_echo("AZ\n", t0), Next::result);
  EXPECT_EQ(x.on_result("   1000\r\n", t0), Next::done);
  EXPECT_EQ(x.reply().status, Reply::Status::ok);
  EXPECT_EQ(x.reply().values, std::vector<int64_t>{1000});
  EXPECT_TRUE(track_.answering);
  const auto log = x.take_log();
  ASSERT_EQ(log.size(), 2u);
  EXPECT_EQ(log[0].text, "unit A: echo includes its name");
  EXPECT_EQ(log[1].text, "unit A: result_placement detected: next_line");
  EXPECT_EQ(readings_.placement('A'), ims::ResultPlacement::next_line);
}

TEST_F(ImsExchange, AResultOnItsOwnLineIsNotTakenWhileAnotherIsOwed) {
  late_.owe_result(t0);
  ims::Exchange x = start(z_);
  x.on_echo("AZ\n", t0);
  EXPECT_EQ(x.on_result("   5\r\n", t0), Next::done);
  EXPECT_EQ(x.reply().status, Reply::Status::garbled);
  EXPECT_TRUE(contains(x.reply().text, "may be the late answer")) << x.reply().text;
  EXPECT_TRUE(x.reply().values.empty());
}

TEST_F(ImsExchange, AResultOnTheEchosLineIsNotTakenWhileAnotherIsOwed) {
  late_.owe_result(t0);
  ims::Exchange x = start(z_);
  EXPECT_EQ(x.on_echo("AZ 5\r\n", t0), Next::done);
  EXPECT_EQ(x.reply().status, Reply::Status::garbled);
  EXPECT_TRUE(contains(x.reply().text, "may end with the late answer")) << x.reply().text;
}

TEST_F(ImsExchange, AResultThatIsNoNumberIsOwedAgainAndNotServed) {
  ims::Exchange x = start(z_);
  x.on_echo("AZ\n", t0);
  x.on_result("\"32.\r\n", t0);
  EXPECT_EQ(x.reply().status, Reply::Status::garbled);
  EXPECT_EQ(late_.owed(), 1);
}

TEST_F(ImsExchange, AMissingResultLineIsGarbledAndOwed) {
  ims::Exchange x = start(z_);
  x.on_echo("AZ\n", t0);
  x.on_result_failure(Reply::of(Reply::Status::timeout, "no result line"), t0);
  EXPECT_EQ(x.reply().status, Reply::Status::garbled);
  EXPECT_EQ(x.reply().text, "unit A echoed 'Z' but sent no result line");
  EXPECT_EQ(late_.owed(), 1);
}

TEST_F(ImsExchange, AQueryEchoCutBeforeItsLinefeedOwesItsResult) {
  ims::Exchange x = start(z_);
  x.on_echo_failure(Reply::of(Reply::Status::garbled, "incomplete echo 'Z'"), "Z", t0);
  EXPECT_EQ(x.reply().status, Reply::Status::garbled);
  EXPECT_EQ(late_.owed(), 1);
}

TEST_F(ImsExchange, ANamelessEchoFromAUnitKnownToEchoItsNameIsGarbled) {
  readings_.seen_name_echo('A', true);
  ims::Exchange x = start(z_);
  EXPECT_EQ(x.on_echo("Z\n", t0), Next::done);
  EXPECT_EQ(x.reply().status, Reply::Status::garbled);
  EXPECT_TRUE(contains(x.reply().text, "another unit's late echo")) << x.reply().text;
  EXPECT_FALSE(track_.answering);
}

TEST_F(ImsExchange, AnAnsweringUnitThatFallsSilentMakesANamelessEchoOfItsCommandSuspect) {
  track_.answering = true;
  ims::Exchange silent = start(z_);
  silent.on_echo_failure(Reply::of(Reply::Status::timeout, "no echo from unit A"), "", t0);
  EXPECT_EQ(silent.reply().status, Reply::Status::timeout);
  EXPECT_FALSE(track_.answering);

  ims::UnitTrack b_track;
  ims::Exchange soon = start(b_, z_, b_track);
  soon.on_echo("Z\n", t0 + 100ms);
  EXPECT_EQ(soon.reply().status, Reply::Status::garbled);
  EXPECT_TRUE(contains(soon.reply().text, "went silent")) << soon.reply().text;

  ims::Exchange later = start(b_, z_, b_track);
  later.on_echo("Z\n", t0 + 600ms);
  EXPECT_EQ(later.on_result("   7\r\n", t0 + 600ms), Next::done);
  EXPECT_EQ(later.reply().values, std::vector<int64_t>{7});
}

TEST_F(ImsExchange, TwoSingleModeEchoesInARowNameTheModeAndWarnOnce) {
  std::vector<std::string> texts;
  int warnings = 0;
  for (int i = 0; i < 3; ++i) {
    ims::Exchange x = start(z_);
    x.on_echo_failure(Reply::of(Reply::Status::garbled, "incomplete echo 'AZ'"), "AZ", t0);
    texts.push_back(x.reply().text);
    for (const auto& line : x.take_log()) warnings += line.level == 4;
  }
  EXPECT_EQ(texts[0], "incomplete echo 'AZ'");
  EXPECT_TRUE(contains(texts[1], "Single mode")) << texts[1];
  EXPECT_TRUE(contains(texts[2], "3 times in a row")) << texts[2];
  EXPECT_EQ(warnings, 1);
  ims::Exchange ok = start(z_);
  ok.on_echo("AZ\n", t0);
  EXPECT_EQ(track_.single_mode_echoes, 0);
}

TEST_F(ImsExchange, PinnedReadingsRefuseTheOtherLayoutAndNameTheOption) {
  readings_.pin('A', {ims::ResultPlacement::echo_line, ims::EchoLinefeed::at_execution});
  ims::Exchange query = start(z_);
  query.on_echo("AZ\n", t0);
  query.on_result("   5\r\n", t0);
  EXPECT_EQ(query.reply().status, Reply::Status::garbled);
  EXPECT_TRUE(contains(query.reply().text, "result_placement: echo_line")) << query.reply().text;

  ims::Exchange command = start(v_);
  EXPECT_EQ(command.on_echo("AV2000\n", t0), Next::done);
  EXPECT_EQ(command.reply().status, Reply::Status::garbled);
  EXPECT_TRUE(contains(command.reply().text, "echo_linefeed: at_execution"))
      << command.reply().text;
}

TEST_F(ImsExchange, AnEchoWhoseLinefeedCameAtOnceWaitsForTheCompletionAndAccountsWhatCame) {
  late_.owe_result(t0);
  ims::Exchange x = start(v_);
  EXPECT_EQ(x.on_echo("AV2000\n", t0), Next::completion);
  EXPECT_EQ(x.on_completion("   9\r\n", t0), Next::done);
  EXPECT_EQ(x.reply().status, Reply::Status::ok);
  EXPECT_EQ(late_.owed(), 0);  // the stray result paid the debt

  ims::Exchange held = start(v_);
  EXPECT_EQ(held.on_echo("AV2000\r\n", t0), Next::done);
  EXPECT_EQ(held.reply().status, Reply::Status::ok);
}

TEST_F(ImsExchange, ALostLinkEndsTheExchangeWithoutOwingAnything) {
  track_.answering = true;
  ims::Exchange x = start(z_);
  x.on_echo("AZ\n", t0);
  x.on_result_failure(Reply::of(Reply::Status::link_down, "gone"), t0);
  EXPECT_EQ(x.reply().status, Reply::Status::link_down);
  EXPECT_EQ(late_.owed(), 0);
  EXPECT_TRUE(track_.answering);
}

}  // namespace
}  // namespace fieldgate
