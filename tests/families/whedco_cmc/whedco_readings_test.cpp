// Every reading of the manual excerpt's open questions (drivers/whedco_cmc/README.md), each
// presented by the simulator: status words in decimal, hex or binary; the non-echo FC number
// for Unit Functional (0 or 8); the power-up state cleared at first contact; replies on their
// own line or on the echo's line. The core read+move scenario runs under each.
#include <gtest/gtest.h>

#include <cstdio>
#include <functional>
#include <thread>

#include "drivers/whedco_cmc/whedco_family.hpp"
#include "line_transport.hpp"
#include "sim/whedco/cmc_line.hpp"

namespace fieldgate {
namespace {

using Status = Reply::Status;
using whedco::StatusForm;
using namespace std::chrono_literals;

const LinkTiming kTiming{std::chrono::milliseconds(30), std::chrono::milliseconds(5)};

Request read(std::string c) {
  return {std::move(c), Request::Expect::values, NumberFormat::decimal};
}
Request write(std::string c) {
  return {std::move(c), Request::Expect::ack, NumberFormat::decimal};
}

// One CMC-0 at address 4 with axes X Y, presented the way `tweak` says.
class Reading {
 public:
  explicit Reading(
      const std::function<void(sim::whedco::UnitOptions&, sim::whedco::LineOptions&)>& tweak,
      const char* address = "4")
      : line_(options(tweak), sim::SimClock::now()),
        transport_(io_, test::LineTransport::simulated(line_)),
        link_(transport_) {
    std::string error;
    node_ = *WhedcoFamily().parse_address(address, error);
  }
  Reply transact(const Request& r) {
    return test::run(io_, family_.transact(link_, node_, r, kTiming));
  }
  sim::whedco::CmcUnit& unit() { return *line_.unit(4); }
  std::vector<std::string> notes() {
    std::vector<std::string> texts;
    for (auto& note : link_.take_notes()) texts.push_back(std::move(note.text));
    return texts;
  }
  test::LineTransport& transport() { return transport_; }
  const std::vector<std::string>& writes() const { return transport_.writes(); }

  // The core scenario: read positions and status, move X and Y, see the move end.
  void core_scenario() {
    ASSERT_EQ(transact(write("ACX100000")).status, Status::ok);
    ASSERT_EQ(transact(write("ACY100000")).status, Status::ok);
    ASSERT_EQ(transact(write("VX20000")).status, Status::ok);
    ASSERT_EQ(transact(write("AMX1000")).status, Status::ok);
    ASSERT_EQ(transact(write("AMY-500")).status, Status::ok);
    const auto idle = transact(read("RS"));
    ASSERT_EQ(idle.status, Status::ok) << idle.text;
    EXPECT_EQ(idle.values[0] & 1, 0);  // not busy
    const auto fc = transact(read("FC"));
    ASSERT_EQ(fc.status, Status::ok) << fc.text;
    EXPECT_EQ(fc.values[1], 0) << "FC " << fc.values[0];
    ASSERT_EQ(transact(write("RAXY")).status, Status::ok);
    const auto busy = transact(read("RS"));
    ASSERT_EQ(busy.status, Status::ok) << busy.text;
    EXPECT_EQ(busy.values[0] & 1, 1);
    EXPECT_EQ(transact(read("RSX")).values[0] & 1, 1);
    int64_t status = 1;
    for (int i = 0; i < 100 && (status & 1); ++i) {
      std::this_thread::sleep_for(10ms);
      const auto r = transact(read("RS"));
      ASSERT_EQ(r.status, Status::ok) << r.text;
      status = r.values[0];
    }
    EXPECT_EQ(status & 1, 0);
    EXPECT_EQ(transact(read("RPX")).values, std::vector<int64_t>{1000});
    EXPECT_EQ(transact(read("RCY")).values, std::vector<int64_t>{-500});
    EXPECT_EQ(transact(read("FC")).values[1], 0);
  }

 private:
  static sim::whedco::LineOptions options(
      const std::function<void(sim::whedco::UnitOptions&, sim::whedco::LineOptions&)>& tweak) {
    sim::whedco::LineOptions o;
    o.units = sim::whedco::parse_units("4", "XY", "", "");
    tweak(o.units[0], o);
    return o;
  }

  asio::io_context io_;
  sim::whedco::CmcLine line_;
  test::LineTransport transport_;
  Link link_;
  WhedcoFamily family_;
  NodeAddress node_;
};

// --- Status words -------------------------------------------------------------------------

std::string as(StatusForm form, int word) {
  char buffer[24];
  switch (form) {
    case StatusForm::hex:
      std::snprintf(buffer, sizeof buffer, "%04X", word);
      return buffer;
    case StatusForm::binary: {
      std::string bits;
      for (int b = 15; b >= 0; --b) bits += ((word >> b) & 1) ? '1' : '0';
      return bits;
    }
    case StatusForm::decimal:
      break;
  }
  return std::to_string(word);
}

TEST(WhedcoStatusWord, EveryBitUnderEveryForm) {
  for (const StatusForm form : {StatusForm::decimal, StatusForm::hex, StatusForm::binary}) {
    for (int bit = 0; bit < 16; ++bit) {
      const int word = 1 << bit;
      std::string problem;
      // Unknown form first (detection), then with the unit's form known.
      for (const auto known : {std::optional<StatusForm>{}, std::optional<StatusForm>{form}}) {
        const std::string text = as(form, word);
        const auto w = whedco::parse_status_word(text, known, problem);
        ASSERT_TRUE(w) << text << ": " << problem;
        // The one ambiguity left: hex digits without letters and without a leading zero
        // ("1000" = bit 12) read as decimal until the unit has shown hex (README).
        const bool ambiguous = !known && form == StatusForm::hex && text.front() != '0' &&
                               text.find_first_not_of("0123456789") == std::string::npos;
        EXPECT_EQ(w->value, ambiguous ? std::stoi(text) : word)
            << whedco::to_string(form) << " '" << text << "'";
      }
    }
  }
}

TEST(WhedcoStatusWord, FormsFromIndependentImplementations) {
  std::string problem;
  // Binary: was served as 44554 (11000000010 wrapped to 16 bits).
  const auto binary = whedco::parse_status_word("0000011000000010", {}, problem);
  ASSERT_TRUE(binary);
  EXPECT_EQ(binary->value, 0x0602);
  EXPECT_EQ(binary->evidence, StatusForm::binary);
  // Hex: was read as decimal 602.
  const auto hex = whedco::parse_status_word("0602", {}, problem);
  ASSERT_TRUE(hex);
  EXPECT_EQ(hex->value, 0x0602);
  EXPECT_EQ(hex->evidence, StatusForm::hex);
  // A unit known to print hex: its unpadded words are hex too.
  EXPECT_EQ(whedco::parse_status_word("602", StatusForm::hex, problem)->value, 0x602);
  EXPECT_EQ(whedco::parse_status_word("602", {}, problem)->value, 602);
  // What does not fit 16 bits is refused, never wrapped.
  EXPECT_FALSE(whedco::parse_status_word("11000000010", {}, problem));
  EXPECT_NE(problem.find("16 bits"), std::string::npos) << problem;
  EXPECT_FALSE(whedco::parse_status_word("65536", {}, problem));
  EXPECT_FALSE(whedco::parse_status_word("1FFFF", {}, problem));
  EXPECT_FALSE(whedco::parse_status_word("12.5", {}, problem));
  // Hex letters as printed, upper case: a lower-case one is garbled (0x0614 read as 0x06a4).
  EXPECT_FALSE(whedco::parse_status_word("06a4", {}, problem));
  EXPECT_FALSE(whedco::parse_status_word("6a4", StatusForm::hex, problem));
}

TEST(WhedcoStatusWord, FamilyRejectsAWordThatDoesNotFit) {
  WhedcoExchange x;
  x.line = "4RSX";
  x.mode = whedco::EchoMode::non_echo;
  x.expect = Request::Expect::values;
  x.kind = whedco::QueryKind::status_word;
  EXPECT_EQ(interpret_whedco_reply(x, "11000000010\r\n*").status, Status::garbled);
  WhedcoFindings found;
  const auto r = interpret_whedco_reply(x, "0602\r\n*", &found);
  ASSERT_EQ(r.status, Status::ok);
  EXPECT_EQ(r.values, std::vector<int64_t>{0x602});
  EXPECT_EQ(found.status_form, StatusForm::hex);
}

class StatusForms : public ::testing::TestWithParam<std::tuple<StatusForm, bool>> {};

TEST_P(StatusForms, CoreScenarioAndTheFaultedBit) {
  const auto [form, echo] = GetParam();
  Reading r([&](sim::whedco::UnitOptions& u, sim::whedco::LineOptions&) {
    u.status_format = form == StatusForm::hex      ? sim::whedco::StatusFormat::hex
                      : form == StatusForm::binary ? sim::whedco::StatusFormat::binary
                                                   : sim::whedco::StatusFormat::decimal;
    u.echo = echo;
  });
  r.core_scenario();
  ASSERT_TRUE(r.unit().inject_fault('Y', 3, sim::SimClock::now()));
  EXPECT_EQ(r.transact(read("RSY")).values[0] & 2, 2);  // faulted
  EXPECT_EQ(r.transact(read("RSX")).values[0] & 2, 0);
  EXPECT_EQ(r.transact(read("RS")).values[0] & 2, 2);
}

INSTANTIATE_TEST_SUITE_P(Whedco, StatusForms,
                         ::testing::Combine(::testing::Values(StatusForm::decimal, StatusForm::hex,
                                                              StatusForm::binary),
                                            ::testing::Bool()));

TEST(WhedcoReadings, HexStatusFormIsDetectedAndLogged) {
  Reading r([](sim::whedco::UnitOptions& u, sim::whedco::LineOptions&) {
    u.status_format = sim::whedco::StatusFormat::hex;
  });
  EXPECT_EQ(r.transact(read("RS")).status, Status::ok);
  bool logged = false;
  for (const auto& n : r.notes()) logged = logged || n.find("printed in hex") != std::string::npos;
  EXPECT_TRUE(logged);
}

// --- Fault codes and the power-up state ----------------------------------------------------

// A unit reading the FCa code table for FC in non-echo format: 8 = Unit Functional. Every move
// failed with the family's old reading (0 = functional).
TEST(WhedcoReadings, NonEchoFcWith8ForUnitFunctional) {
  Reading r(
      [](sim::whedco::UnitOptions& u, sim::whedco::LineOptions&) {
        u.echo = false;
        u.fc_table_codes = true;
      },
      "4/non-echo");
  EXPECT_EQ(r.transact(read("FC")).values, (std::vector<int64_t>{8, 0}));
  r.core_scenario();
  ASSERT_TRUE(r.unit().inject_fault('X', 6, sim::SimClock::now()));
  EXPECT_EQ(r.transact(read("FC")).values[1], 1);
}

TEST(WhedcoReadings, PowerUpWithFcTableCodesIsClearedAndTheFunctionalCodeLearned) {
  Reading r(
      [](sim::whedco::UnitOptions& u, sim::whedco::LineOptions&) {
        u.echo = false;
        u.fc_table_codes = true;
        u.power_failure = true;
      },
      "4/non-echo");
  r.core_scenario();
  EXPECT_EQ(r.writes()[0], "4FC\r");
  bool learned = false;
  for (const auto& n : r.notes())
    learned = learned || n.find("Unit Functional as 8") != std::string::npos;
  EXPECT_TRUE(learned);
  // Learned: a 0 (Power Failure in this reading) is a fault now.
  r.unit().power_cycle(sim::SimClock::now());
  EXPECT_EQ(r.transact(read("FC")).values[1], 1);
}

TEST(WhedcoReadings, PowerUpStateIsClearedAtFirstContactInEveryFormat) {
  for (const bool echo : {true, false}) {
    Reading r(
        [&](sim::whedco::UnitOptions& u, sim::whedco::LineOptions&) {
          u.echo = echo;
          u.power_failure = true;
        },
        echo ? "4" : "4/non-echo");
    r.core_scenario();
    const auto notes = r.notes();
    bool cleared = false;
    for (const auto& n : notes) cleared = cleared || n.find("sent WB") != std::string::npos;
    EXPECT_TRUE(cleared) << (echo ? "echo" : "non-echo");
  }
}

TEST(WhedcoReadings, ARealFaultAtFirstContactIsNotCleared) {
  for (const bool echo : {true, false}) {
    Reading r([&](sim::whedco::UnitOptions& u, sim::whedco::LineOptions&) { u.echo = echo; },
              echo ? "4" : "4/non-echo");
    ASSERT_TRUE(r.unit().inject_fault('Y', 3, sim::SimClock::now()));
    EXPECT_EQ(r.transact(read("FCY")).values, (std::vector<int64_t>{3, 1}));
    for (const auto& w : r.writes()) EXPECT_NE(w, "4WB\r");
  }
}

// --- Reply layout ---------------------------------------------------------------------------

TEST(WhedcoReadings, CoreScenarioWithEveryReplyStyle) {
  for (const auto style : {sim::whedco::ReplyStyle::compact, sim::whedco::ReplyStyle::terminal,
                           sim::whedco::ReplyStyle::inline_echo}) {
    for (const bool echo : {true, false}) {
      SCOPED_TRACE(testing::Message() << "style " << static_cast<int>(style) << " echo " << echo);
      Reading r([&](sim::whedco::UnitOptions& u, sim::whedco::LineOptions& l) {
        u.echo = echo;
        l.style = style;
      });
      r.core_scenario();
    }
  }
}

// --- Transaction integrity (issue 12) ---------------------------------------------------------

// A unit slower than the reply timeout. In non-echo format nothing in a reply names its request,
// so a late value must never be served as the answer to the next query, and a late prompt never
// confirm the next command.
TEST(WhedcoIntegrity, LateRepliesNeverAnswerAnotherRequest) {
  for (const bool echo : {false, true}) {
    SCOPED_TRACE(echo ? "echo" : "non-echo");
    Reading r([&](sim::whedco::UnitOptions& u, sim::whedco::LineOptions&) { u.echo = echo; },
              echo ? "4/echo" : "4/non-echo");
    ASSERT_EQ(r.transact(write("V1=1111")).status, Status::ok);
    ASSERT_EQ(r.transact(write("V2=2222")).status, Status::ok);
    r.transport().set_reply_delay(45ms);  // reply timeout 30 ms
    int wrong = 0, confirmed_refusals = 0;
    for (int i = 0; i < 10; ++i) {
      const auto v1 = r.transact(read("V1=?"));
      if (v1.status == Status::ok && v1.values != std::vector<int64_t>{1111}) ++wrong;
      const auto v2 = r.transact(read("V2=?"));
      if (v2.status == Status::ok && v2.values != std::vector<int64_t>{2222}) ++wrong;
      // The unit lacks axis W and refuses this line ('?'): a late prompt must not confirm it.
      if (r.transact(write("RA[4]")).status == Status::ok) ++confirmed_refusals;
    }
    EXPECT_EQ(wrong, 0);
    EXPECT_EQ(confirmed_refusals, 0);
    r.transport().set_reply_delay(0ms);
    EXPECT_EQ(r.transact(read("V2=?")).values, std::vector<int64_t>{2222});
  }
}

}  // namespace
}  // namespace fieldgate
