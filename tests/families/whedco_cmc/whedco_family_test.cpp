// WhedcoFamily: what replies mean (pure), transactions against the simulated line in process,
// resynchronisation after failures, and the model checks at load.
#include <gtest/gtest.h>

#include <optional>

#include "drivers/whedco_cmc/whedco_family.hpp"
#include "mapping/model_loader.hpp"
#include "tests/families/whedco_cmc/line_transport.hpp"
#include "tests/harness/random_text.hpp"

namespace fieldgate {
namespace {

using whedco::EchoMode;
using whedco::QueryKind;
using Status = Reply::Status;

WhedcoExchange query(std::string line, EchoMode mode = EchoMode::automatic,
                     QueryKind kind = QueryKind::plain, int unit_ratio = 1) {
  WhedcoExchange x;
  x.line = std::move(line);
  x.mode = mode;
  x.expect = Request::Expect::values;
  x.kind = kind;
  x.unit_ratio = unit_ratio;
  return x;
}

WhedcoExchange command(std::string line, EchoMode mode = EchoMode::automatic) {
  WhedcoExchange x;
  x.line = std::move(line);
  x.mode = mode;
  return x;
}

std::vector<int64_t> values(const Reply& r) {
  EXPECT_EQ(r.status, Status::ok) << r.text;
  return r.values;
}

TEST(WhedcoInterpret, ValueWithOrWithoutEchoAndLineEnds) {
  EXPECT_EQ(values(interpret_whedco_reply(query("4RPX"), "1250\r\n*")), std::vector<int64_t>{1250});
  EXPECT_EQ(values(interpret_whedco_reply(query("4RPX"), "4RPX\r\n1250\r\n*")),
            std::vector<int64_t>{1250});
  EXPECT_EQ(values(interpret_whedco_reply(query("4RPX", EchoMode::echo), "4RPX\r1250\r*")),
            std::vector<int64_t>{1250});
  EXPECT_EQ(
      values(interpret_whedco_reply(query("4RPX", EchoMode::non_echo), "\r\n +1250\r\n\r\n*")),
      std::vector<int64_t>{1250});
  EXPECT_EQ(values(interpret_whedco_reply(query("4RPX"), "\n-7\n*")), std::vector<int64_t>{-7});
  EXPECT_EQ(values(interpret_whedco_reply(query("4V1=?"), "V1=-25000\r\n*")),
            std::vector<int64_t>{-25000});
}

TEST(WhedcoInterpret, UserUnitsBecomeInternalWithTheUnitRatio) {
  EXPECT_EQ(values(interpret_whedco_reply(
                query("4RPX", EchoMode::automatic, QueryKind::plain, 1000), "-12.5\r\n*")),
            std::vector<int64_t>{-12500});
  EXPECT_EQ(values(interpret_whedco_reply(query("4AMX?", EchoMode::automatic, QueryKind::plain, 3),
                                          "0.3333\r\n*")),
            std::vector<int64_t>{1});
  const auto r = interpret_whedco_reply(query("4RPX", EchoMode::automatic, QueryKind::plain, 10000),
                                        "999999999999999999\r\n*");
  EXPECT_EQ(r.status, Status::garbled);
  EXPECT_NE(r.text.find("out of range"), std::string::npos) << r.text;
}

TEST(WhedcoInterpret, CommandsAreAnsweredByThePromptAlone) {
  EXPECT_EQ(interpret_whedco_reply(command("4HT"), "*").status, Status::ok);
  EXPECT_EQ(interpret_whedco_reply(command("4HT"), "\r\n*").status, Status::ok);
  EXPECT_EQ(interpret_whedco_reply(command("4AMX5", EchoMode::echo), "4AMX5\r\n*").status,
            Status::ok);
  // Text before the prompt is the unit refusing the line.
  const auto r = interpret_whedco_reply(command("4AMX99999999"), "?\r\n*");
  EXPECT_EQ(r.status, Status::device_error);
  EXPECT_EQ(r.device_code, whedco::kRejected);
  EXPECT_EQ(r.text, "unit answered '?' to '4AMX99999999'");
  EXPECT_EQ(interpret_whedco_reply(command("4XYZ"), "Illegal Command\r\n*").status,
            Status::device_error);
}

TEST(WhedcoInterpret, BadRepliesHavePreciseStatus) {
  const auto no_value = interpret_whedco_reply(query("4RPX"), "\r\n*");
  EXPECT_EQ(no_value.status, Status::garbled);
  EXPECT_NE(no_value.text.find("without a value"), std::string::npos);
  const auto refused = interpret_whedco_reply(query("4RPQ"), "?\r\n*");
  EXPECT_EQ(refused.status, Status::device_error);
  EXPECT_EQ(refused.device_code, whedco::kRejected);
  EXPECT_EQ(interpret_whedco_reply(query("4RPX"), "12\x01\x7f*").status, Status::garbled);
  EXPECT_EQ(interpret_whedco_reply(query("4RPX"), "12-3\r\n*").status, Status::garbled);
  const auto corrupted = interpret_whedco_reply(query("4RPX"), "4RQX\r\n1250\r\n*");
  EXPECT_EQ(corrupted.status, Status::garbled);
  EXPECT_NE(corrupted.text.find("corrupted echo"), std::string::npos) << corrupted.text;
}

TEST(WhedcoInterpret, ConfiguredFormatMustMatchTheUnit) {
  const auto missing = interpret_whedco_reply(query("4RPX", EchoMode::echo), "1250\r\n*");
  EXPECT_EQ(missing.status, Status::garbled);
  EXPECT_NE(missing.text.find("non-echo"), std::string::npos) << missing.text;
  const auto unexpected =
      interpret_whedco_reply(query("4RPX", EchoMode::non_echo), "4RPX\r\n1250\r\n*");
  EXPECT_EQ(unexpected.status, Status::garbled);
  EXPECT_NE(unexpected.text.find("set to echo"), std::string::npos) << unexpected.text;
}

// §6.2: code and faulted flag, from the non-echo hex digit or the echo text.
TEST(WhedcoInterpret, AxisFaultCodeAndFlag) {
  const auto fc = [](std::string frame) {
    return values(
        interpret_whedco_reply(query("4FCX", EchoMode::automatic, QueryKind::axis_fault), frame));
  };
  EXPECT_EQ(fc("8\r\n*"), (std::vector<int64_t>{8, 0}));
  EXPECT_EQ(fc("A\r\n*"), (std::vector<int64_t>{10, 1}));
  EXPECT_EQ(fc("0\r\n*"), (std::vector<int64_t>{0, 1}));
  EXPECT_EQ(fc("4FCX\r\nUnit Functional\r\n*"), (std::vector<int64_t>{8, 0}));
  EXPECT_EQ(fc("4FCX\r\nExcessive Following Error\r\n*"), (std::vector<int64_t>{3, 1}));
  EXPECT_EQ(fc("\r\n Motor Stalled\r\n*"), (std::vector<int64_t>{10, 1}));
  const auto r =
      interpret_whedco_reply(query("4FCX", EchoMode::automatic, QueryKind::axis_fault), "?\r\n*");
  EXPECT_EQ(r.status, Status::device_error);
}

// §6.1.2: FC numbers pass through; echo texts are encoded as base*256 + axis byte.
TEST(WhedcoInterpret, UnitFaultCodeAndFlag) {
  const auto fc = [](std::string frame, NumberFormat format = NumberFormat::decimal) {
    auto x = query("4FC", EchoMode::automatic, QueryKind::unit_fault);
    x.format = format;
    return values(interpret_whedco_reply(x, frame));
  };
  EXPECT_EQ(fc("0\r\n*"), (std::vector<int64_t>{0, 0}));
  EXPECT_EQ(fc("273\r\n*"), (std::vector<int64_t>{273, 1}));
  EXPECT_EQ(fc("111\r\n*", NumberFormat::hex), (std::vector<int64_t>{0x111, 1}));
  EXPECT_EQ(fc("4FC\r\nUnit Functional\r\n*"), (std::vector<int64_t>{0, 0}));
  EXPECT_EQ(fc("4FC\r\nX Faulted\r\n*"), (std::vector<int64_t>{0x11, 1}));
  EXPECT_EQ(fc("4FC\r\nPower Failure\r\nY Faulted\r\n*"), (std::vector<int64_t>{0x122, 1}));
}

TEST(WhedcoInterpret, InputsAsNumberOrBitString) {
  const auto rdi = [](std::string frame) {
    return values(
        interpret_whedco_reply(query("4RDI", EchoMode::automatic, QueryKind::bit_list), frame));
  };
  EXPECT_EQ(rdi("2049\r\n*"), std::vector<int64_t>{2049});
  EXPECT_EQ(rdi("100000000001\r\n*"), std::vector<int64_t>{2049});
}

// --- Transactions -----------------------------------------------------------------------------

const LinkTiming kTiming{std::chrono::milliseconds(30), std::chrono::milliseconds(5)};

NodeAddress node(const char* text) {
  std::string error;
  return *WhedcoFamily().parse_address(text, error);
}

Request read(std::string c, NumberFormat format = NumberFormat::decimal) {
  return {std::move(c), Request::Expect::values, format};
}
Request write(std::string c) {
  return {std::move(c), Request::Expect::ack, NumberFormat::decimal};
}

class WhedcoOnSimulatedLine : public ::testing::Test {
 protected:
  WhedcoOnSimulatedLine()
      : line_(make_options(), sim::SimClock::now()),
        transport_(io_, test::LineTransport::simulated(line_)),
        link_(transport_) {}

  static sim::whedco::LineOptions make_options() {
    sim::whedco::LineOptions o;
    o.units = sim::whedco::parse_units("4,5", "4:XY,5:WXYZ", "5", "");
    return o;
  }
  Reply transact(const char* address, const Request& r) {
    return test::run(io_, family_.transact(link_, node(address), r, kTiming));
  }

  asio::io_context io_;
  sim::whedco::CmcLine line_;
  test::LineTransport transport_;
  Link link_;
  WhedcoFamily family_;
};

// --- Proof of alignment (drivers/alignment_proof.hpp) ---------------------------------------

AlignmentResult prove(asio::io_context& io, Link& link, WhedcoFamily& family,
                      const NodeAddress& address) {
  const auto proof = family.alignment_proof(family.context_of(address), kTiming);
  EXPECT_TRUE(proof);
  if (!proof) return {};
  return test::run(io, prove_alignment(link, *proof, kTiming, kTiming.byte_timeout, 3));
}

TEST_F(WhedcoOnSimulatedLine, AlignmentProofInEveryFormat) {
  for (const char* address : {"4", "4/echo", "5", "5/non-echo"}) {
    const auto result = prove(io_, link_, family_, node(address));
    EXPECT_TRUE(result.proved) << address << ": " << result.why;
    EXPECT_EQ(result.attempts, 1) << address;
    EXPECT_TRUE(result.strays.empty()) << address;
  }
  EXPECT_EQ(transport_.writes(), (std::vector<std::string>{"4!\r", "4FC\r", "4!\r", "4FC\r", "5!\r",
                                                           "5FC\r", "5!\r", "5FC\r"}));
}

// A configured format the unit contradicts proves nothing.
TEST_F(WhedcoOnSimulatedLine, AlignmentProofNeedsTheConfiguredFormat) {
  EXPECT_FALSE(prove(io_, link_, family_, node("5/echo")).proved);
  EXPECT_FALSE(prove(io_, link_, family_, node("4/non-echo")).proved);
}

// A late value reply still in the line after the guard is drained ahead of the first answer; a
// late prompt equal to the first answer is taken for it, and the second step then reads the
// real first answer and fails, until the answers come in step.
TEST(WhedcoAlignmentProof, LateRepliesAreDrainedOrMakeAStepFail) {
  {
    asio::io_context io;
    test::LineTransport transport(io, test::LineTransport::scripted({"1250\r\n*"
                                                                     "*",
                                                                     "0\r\n*"}));
    Link link(transport);
    WhedcoFamily family;
    const auto result = prove(io, link, family, node("4/non-echo"));
    EXPECT_TRUE(result.proved) << result.why;
    EXPECT_EQ(result.strays, std::vector<std::string>{"1250\r\n*"});
  }
  {
    asio::io_context io;
    // The second attempt runs the steps in reverse order (4FC, then 4!).
    test::LineTransport transport(io, test::LineTransport::scripted({"*"
                                                                     "*",
                                                                     "0\r\n*", "0\r\n*", "*"}));
    Link link(transport);
    WhedcoFamily family;
    const auto result = prove(io, link, family, node("4/non-echo"));
    EXPECT_TRUE(result.proved) << result.why;
    EXPECT_EQ(result.attempts, 2);
  }
}

TEST_F(WhedcoOnSimulatedLine, UnitRatioIsReadOnceAndConvertsBothWays) {
  line_.unit(4)->execute("URX1000", sim::SimClock::now());
  EXPECT_EQ(transact("4", write("AMX12500")).status, Status::ok);
  // The first exchange with a unit reads its fault state (first contact).
  EXPECT_EQ(transport_.writes(), (std::vector<std::string>{"4FC\r", "4URX?\r", "4AMX12.5\r"}));
  const auto r = transact("4", read("AMX?"));
  EXPECT_EQ(r.values, std::vector<int64_t>{12500}) << r.text;
  EXPECT_EQ(transport_.writes().back(), "4AMX?\r");
  // Another host changes the ratio: until the family sees URX? (the model polls it) or writes
  // URX itself, it converts with the old one.
  line_.unit(4)->execute("URX500", sim::SimClock::now());
  EXPECT_EQ(transact("4", read("AMX?")).values, std::vector<int64_t>{25000});
  EXPECT_EQ(transact("4", read("URX?")).values, std::vector<int64_t>{500});
  EXPECT_EQ(transact("4", read("AMX?")).values, std::vector<int64_t>{12500});
  EXPECT_EQ(transact("4", write("URX1")).status, Status::ok);
  EXPECT_EQ(transact("4", read("AMX?")).values, std::vector<int64_t>{12500});
  EXPECT_EQ(transport_.writes().back(), "4AMX?\r");
}

// Sending ahead (drivers/README.md): pipelined_request() gives the line the next transact()
// for that request sends with no exchange before it, or nothing.
TEST_F(WhedcoOnSimulatedLine, RequestSentAheadIsTheLineItsExchangeSends) {
  line_.unit(4)->execute("URX1000", sim::SimClock::now());
  NodeContext& unit4 = family_.context_of(node("4"));
  const auto sends_exactly = [&](const Request& r, const std::string& ahead) {
    const std::size_t before = transport_.writes().size();
    const Reply reply = transact("4", r);
    EXPECT_EQ(reply.status, Status::ok) << reply.text;
    ASSERT_EQ(transport_.writes().size(), before + 1) << r.command;
    EXPECT_EQ(transport_.writes().back(), ahead) << r.command;
  };
  // First contact (FC) comes before any request to a unit.
  EXPECT_FALSE(family_.pipelined_request(unit4, read("RS")));
  EXPECT_EQ(transact("4", read("RS")).status, Status::ok);
  const auto rs = family_.pipelined_request(unit4, read("RS"));
  ASSERT_TRUE(rs);
  EXPECT_EQ(*rs, "4RS\r");
  sends_exactly(read("RS"), *rs);
  // A quantity in user units before the axis's unit ratio is known: URX? comes first.
  EXPECT_FALSE(family_.pipelined_request(unit4, write("AMX12500")));
  EXPECT_EQ(transact("4", write("AMX12500")).status, Status::ok);
  EXPECT_EQ(transport_.writes().back(), "4AMX12.5\r");
  const auto amx = family_.pipelined_request(unit4, write("AMX25000"));
  ASSERT_TRUE(amx);
  EXPECT_EQ(*amx, "4AMX25\r");
  sends_exactly(write("AMX25000"), *amx);
  // Axis Y's ratio is still unread, and no unit takes a bus-wide request.
  EXPECT_FALSE(family_.pipelined_request(unit4, write("AMY100")));
  Request everyone = read("RS");
  everyone.bus_wide = true;
  EXPECT_FALSE(family_.pipelined_request(unit4, everyone));
  // After a failure the line is voided before the next request: nothing goes ahead of that.
  EXPECT_EQ(transact("6", read("RS")).status, Status::timeout);
  EXPECT_FALSE(family_.pipelined_request(unit4, read("RS")));
  EXPECT_EQ(transact("4", read("RS")).status, Status::ok);
  const auto again = family_.pipelined_request(unit4, read("RS"));
  ASSERT_TRUE(again);
  sends_exactly(read("RS"), *again);
}

TEST_F(WhedcoOnSimulatedLine, EchoAndNonEchoUnitsOnOneLine) {
  EXPECT_EQ(transact("4", read("V1=?")).values, std::vector<int64_t>{0});
  EXPECT_EQ(transact("5/non-echo", write("V1=-42")).status, Status::ok);
  EXPECT_EQ(transact("5/non-echo", read("V1=?")).values, std::vector<int64_t>{-42});
  EXPECT_EQ(transact("4/echo", read("V1=?")).values, std::vector<int64_t>{0});
  // Configured wrongly: the replies say so.
  const auto wrong = transact("5/echo", read("V1=?"));
  EXPECT_EQ(wrong.status, Status::garbled);
  EXPECT_NE(wrong.text.find("non-echo"), std::string::npos);
}

TEST_F(WhedcoOnSimulatedLine, FaultsInBothFormats) {
  ASSERT_TRUE(line_.unit(4)->inject_fault('Y', 3, sim::SimClock::now()));
  ASSERT_TRUE(line_.unit(5)->inject_fault('Z', 10, sim::SimClock::now()));
  EXPECT_EQ(transact("4", read("FCY")).values, (std::vector<int64_t>{3, 1}));
  EXPECT_EQ(transact("4", read("FCX")).values, (std::vector<int64_t>{8, 0}));
  EXPECT_EQ(transact("4", read("FC")).values, (std::vector<int64_t>{0x22, 1}));
  EXPECT_EQ(transact("5", read("FCZ")).values, (std::vector<int64_t>{10, 1}));
  EXPECT_EQ(transact("5", read("FC")).values, (std::vector<int64_t>{0x88, 1}));
  EXPECT_EQ(transact("4", write("WB")).status, Status::ok);
  EXPECT_EQ(transact("4", read("FC")).values, (std::vector<int64_t>{0, 0}));
  EXPECT_EQ(transact("4", read("FCY")).values, (std::vector<int64_t>{8, 0}));
}

// Issue 49: Power Failure read from a unit whose power-up state was cleared is a controller
// reset, reported once; the unit stays faulted for the PLC's reset (WB). Unit 4 echoes (FC as
// text), unit 5 does not (FCa code 0 shows it).
TEST_F(WhedcoOnSimulatedLine, PowerFailureAfterFirstContactIsAReset) {
  for (const char* address : {"4", "5"}) {
    SCOPED_TRACE(address);
    const char* axis_fault = std::string(address) == "4" ? "FC" : "FCX";
    const auto first = transact(address, read(axis_fault));
    ASSERT_EQ(first.status, Status::ok) << first.text;
    EXPECT_FALSE(first.controller_reset);  // the power-up state first contact cleared
    line_.unit(std::stoi(address))->power_cycle(sim::SimClock::now());
    const auto after = transact(address, read(axis_fault));
    ASSERT_EQ(after.status, Status::ok) << after.text;
    EXPECT_TRUE(after.controller_reset);
    EXPECT_EQ(after.values.at(1), 1);  // still faulted: not cleared behind the PLC's back
    EXPECT_FALSE(transact(address, read(axis_fault)).controller_reset);  // reported once
    EXPECT_EQ(transact(address, write("WB")).status, Status::ok);
    EXPECT_FALSE(transact(address, read(axis_fault)).controller_reset);
    line_.unit(std::stoi(address))->power_cycle(sim::SimClock::now());
    EXPECT_TRUE(transact(address, read(axis_fault)).controller_reset);  // the next one too
  }
}

TEST_F(WhedcoOnSimulatedLine, AxisMaskExpandsAndBadMasksAreNotSent) {
  EXPECT_EQ(transact("4", write("AMX1000")).status, Status::ok);
  EXPECT_EQ(transact("4", write("RA[1]")).status, Status::ok);
  EXPECT_EQ(transport_.writes().back(), "4RAX\r");
  const std::size_t sent = transport_.writes().size();
  const auto r = transact("4", write("SHZ[3]"));
  EXPECT_EQ(r.status, Status::device_error);
  EXPECT_EQ(r.device_code, whedco::kRefusedByGateway);
  EXPECT_EQ(transport_.writes().size(), sent);
  // An axis the unit lacks: the unit itself refuses.
  const auto absent = transact("4", write("RA[4]"));
  EXPECT_EQ(absent.status, Status::device_error);
  EXPECT_EQ(absent.device_code, whedco::kRejected);
}

TEST_F(WhedcoOnSimulatedLine, NoBroadcastAddress) {
  Request r = write("HT");
  r.bus_wide = true;
  const auto reply = transact("4", r);
  EXPECT_EQ(reply.status, Status::device_error);
  EXPECT_EQ(reply.device_code, whedco::kRefusedByGateway);
  EXPECT_TRUE(transport_.writes().empty());
}

TEST_F(WhedcoOnSimulatedLine, SilentUnitTimesOutAndTheLineIsVoidedBeforeTheNextRequest) {
  EXPECT_EQ(transact("6", read("RS")).status, Status::timeout);
  EXPECT_EQ(transact("4", read("RS")).status, Status::ok);
  const auto& w = transport_.writes();
  // First contact with unit 6 (FC) times out, so does the request; unit 4's FC, then RS.
  ASSERT_EQ(w.size(), 6u);
  EXPECT_EQ(w[0], "6FC\r");
  EXPECT_EQ(w[1], "!\r");
  EXPECT_EQ(w[2], "6RS\r");
  EXPECT_EQ(w[3], "!\r");
  EXPECT_EQ(w[4], "4FC\r");
  EXPECT_EQ(w[5], "4RS\r");
}

TEST_F(WhedcoOnSimulatedLine, LinkOpenVoidsAnyPartialLine) {
  test::run(io_, family_.on_link_open(link_, kTiming));
  EXPECT_EQ(transport_.writes(), std::vector<std::string>{"!\r"});
}

TEST(WhedcoScripted, GarbledAndIncompleteRepliesThenResync) {
  asio::io_context io;
  test::LineTransport transport(
      io,
      test::LineTransport::scripted({"0\r\n*", "12\x01*", "", "1250\r\n*", "12", "", "7\r\n*"}));
  Link link(transport);
  WhedcoFamily family;
  const auto first = test::run(io, family.transact(link, node("4"), read("RS"), kTiming));
  EXPECT_EQ(first.status, Status::garbled);
  EXPECT_EQ(test::run(io, family.transact(link, node("4"), read("RS"), kTiming)).values,
            std::vector<int64_t>{1250});
  const auto partial = test::run(io, family.transact(link, node("4"), read("RS"), kTiming));
  EXPECT_EQ(partial.status, Status::garbled);
  EXPECT_NE(partial.text.find("incomplete"), std::string::npos);
  EXPECT_EQ(test::run(io, family.transact(link, node("4"), read("RS"), kTiming)).values,
            std::vector<int64_t>{7});
  EXPECT_EQ(transport.writes(),
            (std::vector<std::string>{"4FC\r", "4RS\r", "!\r", "4RS\r", "4RS\r", "!\r", "4RS\r"}));
}

TEST(WhedcoScripted, UnitRatioThatCannotBeReadFailsTheRequest) {
  asio::io_context io;
  test::LineTransport transport(io, test::LineTransport::scripted({"0\r\n*", "?\r\n*", "0\r\n*"}));
  Link link(transport);
  WhedcoFamily family;
  const auto refused = test::run(io, family.transact(link, node("4"), read("RPX"), kTiming));
  EXPECT_EQ(refused.status, Status::device_error);
  EXPECT_NE(refused.text.find("unit ratio of axis X"), std::string::npos) << refused.text;
  const auto zero = test::run(io, family.transact(link, node("4"), read("RPX"), kTiming));
  EXPECT_EQ(zero.status, Status::garbled);
  EXPECT_EQ(transport.writes(), (std::vector<std::string>{"4FC\r", "4URX?\r", "4URX?\r"}));
}

TEST(WhedcoScripted, OverlongReplyIsGarbled) {
  asio::io_context io;
  test::LineTransport transport(io,
                                test::LineTransport::scripted({"0\r\n*", std::string(2000, '1')}));
  Link link(transport);
  WhedcoFamily family;
  const auto r = test::run(io, family.transact(link, node("4"), read("RS"), kTiming));
  EXPECT_EQ(r.status, Status::garbled);
}

// A model with one status read and the given options; nullopt (and a failure) if invalid.
std::optional<Model> status_model(const std::string& options) {
  const std::string text = "model: m\nfamily: whedco-cmc\n" + options +
                           "poll_classes: {fast: 100ms}\npoints:\n"
                           "  s: {type: uint16, read: RS, poll: fast}\n";
  Diagnostics d;
  const auto model = load_model_text(text, "m.yaml", d);
  EXPECT_TRUE(model && d.ok()) << d.to_text();
  if (!model || !d.ok()) return std::nullopt;
  WhedcoFamily().validate_model(*model, d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  if (!d.ok()) return std::nullopt;
  return *model;
}

// Unit 4 with status_model(options) on a line that answers `replies` in turn; word() reads a
// status word, which must answer.
struct StatusWords {
  StatusWords(std::deque<std::string> replies, const std::string& options)
      : transport(io, test::LineTransport::scripted(std::move(replies))), link(transport) {
    family.configure_node(node("4"), status_model(options).value());
  }
  int64_t word(const char* command) {
    const auto r = test::run(io, family.transact(link, node("4"), read(command), kTiming));
    EXPECT_EQ(r.status, Status::ok) << r.text;
    return r.values.empty() ? int64_t{-1} : r.values[0];
  }

  asio::io_context io;
  test::LineTransport transport;
  Link link;
  WhedcoFamily family;
};

// Section 4.3.1 (the status word layout) is missing, and no word tells the layouts apart: an
// axis word with bit 2 = homed (0x0614: homed, home input, in position, servo) at rest looks
// like a busy word of the outputs layout. The default layout is fixed (busy_first, the models'
// bits): a homed axis at rest stays at rest, whatever words came before.
TEST(WhedcoScripted, HomedAtBit2IsNoBusyAxisUnderTheDefaultLayout) {
  StatusWords words(
      {"0\r\n*", "0\r\n*", "17\r\n*", "1556\r\n*", "1556\r\n*", "1557\r\n*", "1556\r\n*"}, "");
  EXPECT_EQ(words.word("RSX"), 0);
  EXPECT_EQ(words.word("RSX"), 17);     // homing: busy, home input
  EXPECT_EQ(words.word("RSX"), 0x614);  // homed at rest: bit 0 (busy) clear
  EXPECT_EQ(words.word("RSX"), 0x614);
  EXPECT_EQ(words.word("RSX"), 0x615);  // the next move: busy
  EXPECT_EQ(words.word("RSX"), 0x614);  // and at rest again
  EXPECT_TRUE(words.link.take_notes().empty());
}

// Words laid out like the hardware outputs (A.2: set point A, set point B, Busy, Fault), pinned
// by the model, are reported in the layout the models read (busy bit 0, fault bit 1, set points
// at 8 and 9; bits 4-7, Memory Lost 7, stay).
TEST(WhedcoScripted, StatusWordsLaidOutLikeTheOutputsAreRearranged) {
  StatusWords words({"0\r\n*", "0\r\n*", "1\r\n*", "4\r\n*", "13\r\n*", "1\r\n*", "136\r\n*"},
                    "options: {status_layout: outputs}\n");
  EXPECT_EQ(words.word("RS"), 0);
  EXPECT_EQ(words.word("RS"), 0x100);  // set point A alone: not busy
  EXPECT_EQ(words.word("RSX"), 1);     // busy
  EXPECT_EQ(words.word("RS"), 0x103);  // busy, fault, set point A
  EXPECT_EQ(words.word("RS"), 0x100);
  EXPECT_EQ(words.word("RS"), 0x82);  // fault, Memory Lost (bit 7) stays
}

TEST(WhedcoScripted, StatusLayoutPinnedByTheModel) {
  for (const auto& [layout, expected] :
       std::vector<std::pair<std::string, int64_t>>{{"busy_first", 4}, {"outputs", 1}}) {
    const auto model = status_model("options: {status_layout: " + layout + "}\n");
    ASSERT_TRUE(model) << layout;
    WhedcoFamily family;
    family.configure_node(node("4"), *model);
    asio::io_context io;
    test::LineTransport transport(io, test::LineTransport::scripted({"0\r\n*", "4\r\n*"}));
    Link link(transport);
    const auto r = test::run(io, family.transact(link, node("4"), read("RS"), kTiming));
    ASSERT_EQ(r.status, Status::ok) << r.text;
    EXPECT_EQ(r.values, std::vector<int64_t>{expected}) << layout;
  }
  Diagnostics d;
  const auto bad = load_model_text("model: m\nfamily: whedco-cmc\noptions: {status_layout: pins}\n",
                                   "m.yaml", d);
  ASSERT_TRUE(bad) << d.to_text();
  WhedcoFamily().validate_model(*bad, d);
  EXPECT_NE(d.to_text().find("option status_layout: expected busy_first or outputs, found "
                             "'pins'"),
            std::string::npos)
      << d.to_text();
}

TEST(WhedcoFamilyTest, AddressKeepsTheFormatButNotInItsText) {
  EXPECT_EQ(node("4/echo").text, "4");
  EXPECT_EQ(WhedcoFamily::echo_mode(node("4/echo")), EchoMode::echo);
  EXPECT_EQ(WhedcoFamily::echo_mode(node("4/non-echo")), EchoMode::non_echo);
  EXPECT_EQ(WhedcoFamily::echo_mode(node("4")), EchoMode::automatic);
  std::string error;
  EXPECT_FALSE(WhedcoFamily().parse_address("9", error));
  EXPECT_NE(error.find("SW2-1..3"), std::string::npos);
}

TEST(WhedcoFamilyTest, WireEstimateCountsTheEcho) {
  WhedcoFamily f;
  const Request r = read("RPX");
  EXPECT_GT(f.estimate_wire_chars(node("4"), r), f.estimate_wire_chars(node("4/non-echo"), r));
}

// --- Models --------------------------------------------------------------------------------

Diagnostics validate_file(const std::string& path) {
  Diagnostics d;
  const auto model = load_model_file(path, d);
  EXPECT_TRUE(model) << d.to_text();
  if (model) WhedcoFamily().validate_model(*model, d);
  return d;
}

TEST(WhedcoModels, ShippedModelsLoadClean) {
  for (const char* file : {"whedco-cmc.yaml", "whedco-cmc-xy.yaml"}) {
    const auto d = validate_file(std::string(FIELDGATE_SOURCE_DIR "/config/models/") + file);
    EXPECT_TRUE(d.ok()) << file << "\n" << d.to_text();
  }
}

TEST(WhedcoModels, FamilyChecksNameTheLine) {
  const std::string text = R"(model: bad
family: whedco-cmc
options: {echo: "on"}
poll_classes: {fast: 100ms}
points:
  p1: {type: int32, read: AMX5, poll: fast}
  p2: {type: int32, read: RPX, write: RPX, poll: fast}
  p3: {type: int32, read: {request: RPX, format: hex24}, poll: fast}
  p4: {type: int32, write: "AMX.5{value}"}
setpoints:
  axis: {type: uint16, default: 1}
actions:
  a1: {code: 1, steps: [CB]}
  a2: {code: 2, steps: [DE1]}
  a3: {code: 3, steps: [{send: HT, urgent: true}]}
  a4: {code: 4, steps: [HT], bus_wide: true}
  a5: {code: 5, steps: ["4HT"]}
  a6: {code: 6, steps: ["SHZ[{axis}]", "RPX"]}
  a7: {code: 7, steps: ["ht"]}
)";
  Diagnostics d;
  const auto model = load_model_text(text, "bad.yaml", d);
  ASSERT_TRUE(model && d.ok()) << d.to_text();
  WhedcoFamily().validate_model(*model, d);
  const std::string all = d.to_text();
  for (const char* expected : {
           "bad.yaml:3:11: error: model bad: unknown whedco-cmc option 'echo' (known: "
           "status_layout; `fieldgate models --options whedco-cmc` describes them) (the "
           "communication format is set per node in 'address'",
           "bad.yaml:6:7: error: point p1 read: 'AMX5' is no query",
           "bad.yaml:7:7: error: point p2 write: 'RPX' is a query",
           "bad.yaml:8:7: error: point p3: Whedco replies are decimal or hex",
           "bad.yaml:9:7: error: point p4 write: 'AMX.51': numbers the unit ratio scales",
           "error: action a1: 'CB': CB is kept out of the gateway",
           "error: action a2: 'DE1': DE is kept out",
           "error: action a3: whedco-cmc has no urgent commands",
           "bad.yaml:16:7: error: action a4: Whedco CMC units have no broadcast address",
           "error: action a5: '4HT': the family adds the unit address",
           "error: action a6: 'RPX' is a query",
           "error: action a7: 'ht': Whedco commands are upper case",
       })
    EXPECT_NE(all.find(expected), std::string::npos) << "missing: " << expected << "\n" << all;
  EXPECT_EQ(d.errors().size(), 12u) << all;
}

}  // namespace
}  // namespace fieldgate

namespace fieldgate {
namespace {

// Whatever arrives, the family answers with a status: no crash, no exception, no hang.
TEST(WhedcoRobustness, RandomRepliesGetAStatus) {
  test::RandomText text(7, "4RPX*\r\n -+.0123456789AFaf?!=V\x01\xff Faulted Unit Functional", 0,
                        40);
  for (int i = 0; i < 20000; ++i) {
    const std::string frame = text.next() + '*';
    for (const auto kind :
         {QueryKind::plain, QueryKind::axis_fault, QueryKind::unit_fault, QueryKind::bit_list}) {
      auto x = query("4RPX", static_cast<EchoMode>(i % 3), kind, 1 + i % 10000);
      x.format = i % 2 ? NumberFormat::hex : NumberFormat::decimal;
      const auto r = interpret_whedco_reply(x, frame);
      if (r.status == Status::ok) {
        EXPECT_FALSE(r.values.empty()) << frame;
      }
      x.expect = Request::Expect::ack;
      (void)interpret_whedco_reply(x, frame);
    }
    (void)whedco::frame_length(frame, "4RPX", static_cast<EchoMode>(i % 3));
    std::string error;
    if (const auto p = whedco::prepare_command(frame.substr(0, frame.size() - 1), error))
      (void)whedco::wire_command(*p, 1 + i % 10000);
  }
}

}  // namespace
}  // namespace fieldgate
