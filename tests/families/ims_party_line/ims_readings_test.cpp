// Every reading of the manual's reply layout (issue 20) and late replies (issue 12): codec
// vectors, then the core read+move scenario against the simulated chain under each reading,
// pinned readings, and replies delayed past the reply timeout.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

#include <chrono>
#include <random>
#include <thread>

#include "drivers/ims_party_line/ims_codec.hpp"
#include "drivers/ims_party_line/ims_family.hpp"
#include "drivers/ims_party_line/ims_readings.hpp"
#include "tests/families/ims_party_line/ims_chain_bench.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using ims::EchoMatch;

using test::read;
using test::unit;
using test::write;

// --- codec ----------------------------------------------------------------------------------

TEST(ImsEchoLine, TheIssuesExampleResultOnTheEchosLine) {
  // gateway "A Z LF", unit "A Z space 0.00 CR LF"
  const auto e = ims::parse_echo_line('A', "Z", "AZ 0.00\r\n");
  EXPECT_EQ(e.match, EchoMatch::with_name);
  ASSERT_TRUE(e.result);
  EXPECT_EQ(e.result->values, std::vector<int64_t>{0});
  EXPECT_TRUE(e.carriage_return);
}

TEST(ImsEchoLine, EveryPlacementPaddingAndEnd) {
  struct Case {
    const char* line;
    EchoMatch match;
    std::optional<int64_t> value;
    bool cr;
  };
  const Case cases[] = {
      {"AZ\n", EchoMatch::with_name, std::nullopt, false},
      {"Z\n", EchoMatch::without_name, std::nullopt, false},
      {"Z\r\n", EchoMatch::without_name, std::nullopt, true},
      {"AZ   1000\r\n", EchoMatch::with_name, 1000, true},
      {"Z 1000\n", EchoMatch::without_name, 1000, false},
      {"Z1000\r\n", EchoMatch::without_name, 1000, true},
      {"AZ-2500.00\n", EchoMatch::with_name, -2500, false},
      {"Z 12.50\r\n", EchoMatch::without_name, 13, true},
      {"\rAZ 5\r\n", EchoMatch::with_name, 5, true},  // a late completion's CR before the echo
      {"A129  40\r\n", EchoMatch::without_name, 40, true},
      {"AA12940\n", EchoMatch::with_name, 40, false},  // exactly the command, then the value
  };
  for (const auto& c : cases) {
    const char* command =
        std::string_view(c.line).find("129") != std::string_view::npos ? "A129" : "Z";
    const auto e = ims::parse_echo_line('A', command, c.line);
    EXPECT_EQ(e.match, c.match) << ims::printable(c.line);
    EXPECT_EQ(e.result.has_value(), c.value.has_value()) << ims::printable(c.line);
    if (e.result && c.value) {
      EXPECT_EQ(e.result->values.front(), *c.value);
    }
    EXPECT_EQ(e.carriage_return, c.cr) << ims::printable(c.line);
  }
}

TEST(ImsEchoLine, WhatIsNoEchoOfTheRequest) {
  for (const char* line : {"BZ\n", "AZ x\n", "AZ 10 x\n", "   1000\r\n", "A^\n", "AZ"})
    EXPECT_EQ(ims::parse_echo_line('A', "Z", line).match, EchoMatch::mismatch)
        << ims::printable(line);
}

TEST(ImsInterpret, EveryReadingOfAQuery) {
  for (const char* received : {"AZ\n   1000\r\n", "Z\n1000\n", "AZ\r\n 1000.00\r\n", "AZ 1000\r\n",
                               "Z1000\n", "Z   1000.00\r\n"}) {
    const Reply r = interpret_ims_reply(unit('A'), read("Z"), received);
    EXPECT_EQ(r.status, Reply::Status::ok) << ims::printable(received) << ": " << r.text;
    EXPECT_EQ(r.values, std::vector<int64_t>{1000}) << ims::printable(received);
  }
}

TEST(ImsInterpret, EveryReadingOfANonQueryAndWhatCannotAnswerIt) {
  for (const char* received : {"AV2000\n", "V2000\n\r\n", "AV2000\r\n", "V2000\r\n"})
    EXPECT_EQ(interpret_ims_reply(unit('A'), write("V2000"), received).status, Reply::Status::ok)
        << ims::printable(received);
  // A value to a non-query, an ack to a query, another unit's echo: garbled, never ok.
  const Reply value = interpret_ims_reply(unit('A'), write("V2000"), "AV2000 5\r\n");
  EXPECT_EQ(value.status, Reply::Status::garbled);
  EXPECT_NE(value.text.find("has no result"), std::string::npos) << value.text;
  EXPECT_EQ(interpret_ims_reply(unit('A'), read("Z"), "AZ\r\n").status, Reply::Status::garbled);
  EXPECT_EQ(interpret_ims_reply(unit('A'), read("Z"), "BZ 5\r\n").status, Reply::Status::garbled);
  EXPECT_EQ(interpret_ims_reply(unit('A'), read("Z"), "AZ\n\r\n").status, Reply::Status::garbled);
}

TEST(ImsStray, LinesOutsideAnExchange) {
  EXPECT_EQ(ims::classify_stray("\r\n"), ims::StrayLine::blank);
  EXPECT_EQ(ims::classify_stray("   1000\r\n"), ims::StrayLine::result);
  EXPECT_EQ(ims::classify_stray(" 0.00\n"), ims::StrayLine::result);
  EXPECT_EQ(ims::classify_stray("AZ\n"), ims::StrayLine::query_echo);
  EXPECT_EQ(ims::classify_stray("^\n"), ims::StrayLine::query_echo);
  EXPECT_EQ(ims::classify_stray("AV2000\n"), ims::StrayLine::other);
}

TEST(ImsLateReplies, OwedResultsArePaidByStrayResultsAndWrittenOffAfterTheWindow) {
  ims::LateReplies late;
  const auto t0 = ims::Clock::now();
  late.owe_result(t0);
  late.stray("AZ\n", t0);  // a late echo of a query: its result follows
  EXPECT_EQ(late.owed(), 2);
  late.stray("   5\r\n\r\n", t0);
  EXPECT_EQ(late.owed(), 1);
  EXPECT_FALSE(late.expire(t0 + 400ms, 500ms));
  EXPECT_TRUE(late.expire(t0 + 600ms, 500ms));
  EXPECT_EQ(late.owed(), 0);
}

TEST(ImsLateReplies, AnEchoWithoutNameMayBeASilentUnitsLateEcho) {
  ims::LateReplies late;
  const auto t0 = ims::Clock::now();
  late.silent('A', "Z", t0);
  EXPECT_TRUE(late.suspicious('B', "Z", t0 + 10ms, 500ms));
  EXPECT_FALSE(late.suspicious('B', "^", t0 + 10ms, 500ms));
  EXPECT_FALSE(late.suspicious('A', "Z", t0 + 10ms, 500ms));
  EXPECT_FALSE(late.suspicious('B', "Z", t0 + 600ms, 500ms));
  late.stray("Z\n", t0 + 20ms);  // it came
  EXPECT_FALSE(late.suspicious('B', "Z", t0 + 30ms, 500ms));
}

TEST(ImsReadingOptions, Parsed) {
  std::optional<ims::ResultPlacement> p;
  EXPECT_TRUE(ims::parse_result_placement("auto", p));
  EXPECT_FALSE(p);
  EXPECT_TRUE(ims::parse_result_placement("echo_line", p));
  EXPECT_EQ(p, ims::ResultPlacement::echo_line);
  EXPECT_FALSE(ims::parse_result_placement("inline", p));
  std::optional<ims::EchoLinefeed> l;
  EXPECT_TRUE(ims::parse_echo_linefeed("at_execution", l));
  EXPECT_EQ(l, ims::EchoLinefeed::at_execution);
  EXPECT_FALSE(ims::parse_echo_linefeed("late", l));
}

// --- the chain under each reading -----------------------------------------------------------

struct Reading {
  const char* name;
  bool echo_line;
  sim::ims::ResultFormat::Padding padding;
  const char* end;
  sim::ims::ResultFormat::Decimals decimals;
  bool linefeed_at_execution;
  bool echo_name;
  bool completion;
};

std::ostream& operator<<(std::ostream& os, const Reading& r) {
  return os << r.name;
}

using Padding = sim::ims::ResultFormat::Padding;
using Decimals = sim::ims::ResultFormat::Decimals;

const Reading kReadings[] = {
    {"digest", false, Padding::right_aligned, "\r\n", Decimals::variable_resolution, false, false,
     true},
    {"issue_example", true, Padding::space, "\r\n", Decimals::always, true, true, true},
    {"echo_line_bare_lf", true, Padding::none, "\n", Decimals::never, false, false, true},
    {"next_line_bare_lf_decimals", false, Padding::none, "\n", Decimals::always, true, false,
     false},
    {"next_line_name_at_execution", false, Padding::space, "\r\n", Decimals::never, true, true,
     true},
    {"echo_line_padded_no_completion", true, Padding::right_aligned, "\r\n", Decimals::always,
     false, true, false},
};

class ChainFixture : protected test::ImsChainBench {
 protected:
  ChainFixture() : ImsChainBench(LinkTiming{30ms, 5ms}) {}

  void make_chain(const Reading& reading) {
    sim::ims::PartyLineOptions options;
    options.names = {'A', 'B', 'C'};
    options.result_on_echo_line = reading.echo_line;
    options.linefeed_at_execution = reading.linefeed_at_execution;
    options.echo_name = reading.echo_name;
    options.completion = reading.completion;
    options.result_format.padding = reading.padding;
    options.result_format.end = reading.end;
    options.result_format.decimals = reading.decimals;
    attach(std::move(options));
  }

  // What the family noted on the link so far.
  bool logged(const std::string& text) {
    for (auto& note : link_->take_notes()) log_.push_back(std::move(note.text));
    for (const auto& l : log_)
      if (l.find(text) != std::string::npos) return true;
    return false;
  }

  std::vector<std::string> log_;
};

class ImsEveryReading : public ChainFixture, public ::testing::TestWithParam<Reading> {
 protected:
  void SetUp() override { make_chain(GetParam()); }
};

TEST_P(ImsEveryReading, ReadsMovesAndReadsBack) {
  expect_each_axis_reads_its_position();
  // The model's move_absolute: V, K, R; then ^ until idle, then Z.
  for (const char* step : {"V5000", "K0 0", "R1500"}) {
    const Reply r = transact('A', write(step));
    ASSERT_EQ(r.status, Reply::Status::ok) << step << ": " << r.text;
  }
  int64_t status = -1;
  for (int i = 0; i < 100 && status != 0; ++i) {
    const Reply r = transact('A', read("^"));
    ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
    status = r.values.front() & ims::status::meaningful;
    if (status != 0) std::this_thread::sleep_for(10ms);
  }
  EXPECT_EQ(status, 0);
  EXPECT_EQ(transact('A', read("Z")).values, std::vector<int64_t>{1500});
  EXPECT_EQ(transact('A', read("A129")).status, Reply::Status::ok);
  EXPECT_EQ(transact('B', read("Z")).values, std::vector<int64_t>{-2500});

  // The reading each unit was found to use is logged once.
  const Reading& reading = GetParam();
  EXPECT_TRUE(logged(std::string("unit A: result_placement detected: ") +
                     (reading.echo_line ? "echo_line" : "next_line")));
  EXPECT_TRUE(
      logged(std::string("unit A: echo_linefeed detected: ") +
             (reading.linefeed_at_execution && reading.completion ? "at_execution" : "at_once")));
  EXPECT_EQ(family_.readings().placement('B'),
            reading.echo_line ? ims::ResultPlacement::echo_line : ims::ResultPlacement::next_line);
  EXPECT_EQ(family_.readings().echoes_name('C'), reading.echo_name);
}

INSTANTIATE_TEST_SUITE_P(Readings, ImsEveryReading, ::testing::ValuesIn(kReadings),
                         [](const auto& info) { return std::string(info.param.name); });

class ImsPinnedReading : public ChainFixture, public ::testing::Test {};

TEST_F(ImsPinnedReading, AReplyInTheOtherLayoutIsGarbledAndNamesTheOption) {
  make_chain(kReadings[1]);  // the issue's unit: result on the echo's line
  family_.pin('A', {ims::ResultPlacement::next_line, std::nullopt});
  Reply r = transact('A', read("Z"));
  EXPECT_EQ(r.status, Reply::Status::garbled);
  EXPECT_NE(r.text.find("result_placement: next_line"), std::string::npos) << r.text;
  family_.pin('A', {ims::ResultPlacement::echo_line, ims::EchoLinefeed::at_once});
  EXPECT_EQ(transact('A', read("Z")).status, Reply::Status::ok);
  r = transact('A', write("V2000"));
  EXPECT_EQ(r.status, Reply::Status::garbled);
  EXPECT_NE(r.text.find("echo_linefeed: at_once"), std::string::npos) << r.text;
  family_.pin('A', {ims::ResultPlacement::echo_line, ims::EchoLinefeed::at_execution});
  EXPECT_EQ(transact('A', write("V2000")).status, Reply::Status::ok);
}

TEST_F(ImsPinnedReading, ModelOptionsReachTheNode) {
  Model model;
  model.name = "m";
  model.options = {{"result_placement", "echo_line"}, {"echo_linefeed", "at_execution"}};
  family_.configure_node(unit('B'), model);
  EXPECT_EQ(family_.readings().pins('B').placement, ims::ResultPlacement::echo_line);
  EXPECT_EQ(family_.readings().pins('B').linefeed, ims::EchoLinefeed::at_execution);
  EXPECT_FALSE(family_.readings().pins('A').placement);
}

// --- replies later than the reply timeout (issue 12) ----------------------------------------

class ImsLateReplies : public ChainFixture, public ::testing::TestWithParam<Reading> {
 protected:
  void SetUp() override { make_chain(GetParam()); }
};

// Random delays around the reply timeout, random units: every value taken as good is that
// unit's, every write confirmed ran on that unit.
TEST_P(ImsLateReplies, NoValueOrConfirmationFromAnotherRequest) {
  const std::map<char, int64_t> positions{{'A', 1000}, {'B', -2500}, {'C', 123456}};
  for (const auto& [name, p] : positions)
    control("position", {std::string(1, name), std::to_string(p)});
  std::mt19937 random(7);
  const std::chrono::milliseconds delays[] = {0ms, 10ms, 25ms, 40ms, 70ms, 120ms};
  int good = 0, bad = 0, writes_ok = 0;
  for (int i = 0; i < 120; ++i) {
    transport_->faults().reply_delay = delays[random() % std::size(delays)];
    const char name = "ABC"[random() % 3];
    if (random() % 4 == 0) {
      const int outputs = static_cast<int>(random() % 8);
      const std::string command = "A" + std::to_string(8 * outputs);
      const Reply r = transact(name, write(command.c_str()));
      if (r.status == Reply::Status::ok) {
        ++writes_ok;
        EXPECT_EQ(transport_->chain().unit(name)->outputs(), outputs) << "write to " << name;
      }
      continue;
    }
    const Reply r = transact(name, read("Z"));
    if (r.status == Reply::Status::ok) {
      ++good;
      EXPECT_EQ(r.values, std::vector<int64_t>{positions.at(name)}) << "read of " << name;
    } else {
      ++bad;
      EXPECT_NE(r.status, Reply::Status::device_error);
    }
  }
  transport_->faults().reply_delay = 0ms;
  std::this_thread::sleep_for(ImsPartyLineFamily::late_window(timing_) + 150ms);
  for (const auto& [name, p] : positions) {
    const Reply r = transact(name, read("Z"));
    EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
    EXPECT_EQ(r.values, std::vector<int64_t>{p});
  }
  std::cout << "[ measured ] " << GetParam().name << ": " << good << " good reads, " << bad
            << " refused, " << writes_ok << " writes confirmed\n";
  EXPECT_GT(good, 0);
  EXPECT_GT(bad, 0);
}

INSTANTIATE_TEST_SUITE_P(Readings, ImsLateReplies, ::testing::ValuesIn(kReadings),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate
