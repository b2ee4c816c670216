// TechnoFamily::transact() against the simulator in process (real time, short motions): the
// handshake of capital moves at the end of the motion, stop past a held line, the timeout of a
// homing run that never answers, lower-case motion inferred from polls, reply variants.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include <thread>

#include "drivers/techno_c/techno_family.hpp"
#include "mapping/model_loader.hpp"
#include "sim_transport.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

NodeAddress device(int n) {
  return {std::to_string(n), n, 0};
}
Request ack(std::string c) {
  return {std::move(c), Request::Expect::ack, NumberFormat::decimal};
}
Request query(std::string c, NumberFormat f = NumberFormat::hex24) {
  return {std::move(c), Request::Expect::values, f};
}

// A C142-like model whose options make motions short and timeouts tight.
std::string model_text(const std::string& extra_options = "", int travel = 1000,
                       const std::string& margin = "150ms") {
  return "model: bench\nfamily: techno-c\noptions: {variant: c142, axes: 7, acceleration: 100, "
         "travel: " +
         std::to_string(travel) + ", timeout_factor: 1.25, timeout_margin: " + margin +
         ", stop_settle: 300ms, "
         "steps_per_unit: 100, unit_resolution: 0.01" +
         extra_options +
         "}\npoll_classes: {fast: 100ms}\npoints:\n"
         "  x: {type: int32, read: {request: P, field: 0, format: hex24}, poll: fast}\n"
         "actions:\n  k: {code: 1, steps: [k]}\n";
}

asio::awaitable<Reply> urgent_after(TechnoFamily& family, Link& link, std::chrono::milliseconds d,
                                    std::string command) {
  asio::steady_timer t(co_await asio::this_coro::executor, d);
  co_await t.async_wait(asio::as_tuple(asio::use_awaitable));
  co_return co_await family.send_urgent(link, device(0), ack(std::move(command)));
}

class TechnoBench : public ::testing::Test {
 protected:
  void start(sim::techno::ControllerOptions options, const std::string& model = model_text(),
             sim::techno::ExchangeOptions exchange = {}) {
    controller_ = std::make_unique<sim::techno::Controller>(options, sim::SimClock::now());
    exchange_ = std::make_unique<sim::techno::TechnoExchange>(*controller_, exchange, faults_);
    transport_ = std::make_unique<test::SimTransport>(io_, *exchange_);
    link_ = std::make_unique<Link>(*transport_);
    Diagnostics d;
    model_ = load_model_text(model, "bench.yaml", d);
    ASSERT_TRUE(model_ && d.ok()) << d.to_text();
    family_.validate_model(*model_, d);
    ASSERT_TRUE(d.ok()) << d.to_text();
    family_.configure_node(NodeAddress{"0", 0, 0}, *model_);
  }

  static sim::techno::ControllerOptions defined() {
    sim::techno::ControllerOptions o;
    o.axes = 7;
    o.acceleration = 100'000;
    o.home_distance = 500;
    return o;
  }

  Reply transact(const Request& r, int node = 0) {
    return run(family_.transact(*link_, device(node), r, timing_));
  }

  // Polls P every 50 ms, at most `polls` times, until the axis is at rest (field 3 is 0) or a
  // poll fails; returns the last reply, for the caller to check.
  Reply poll_until_at_rest(int polls) {
    Reply p;
    for (int i = 0; i < polls; ++i) {
      std::this_thread::sleep_for(50ms);
      p = transact(query("P"));
      if (p.status != Reply::Status::ok || p.values[3] == 0) break;
    }
    return p;
  }

  // Sends a motion that answers at its start (lower case, or home) and polls until the axis is
  // at rest; the last poll, which must have found it at rest, in *rest. Call it through
  // ASSERT_NO_FATAL_FAILURE.
  void move_to_rest(const std::string& command, int polls, Reply* rest) {
    ASSERT_EQ(transact(ack(command)).status, Reply::Status::ok) << command;
    *rest = poll_until_at_rest(polls);
    ASSERT_EQ(rest->status, Reply::Status::ok) << rest->text;
    EXPECT_EQ(rest->values[3], 0);
  }

  template <typename T>
  T run(asio::awaitable<T> a) {
    return test::run(io_, std::move(a));
  }

  asio::io_context io_;
  sim::FaultInjection faults_;
  std::unique_ptr<sim::techno::Controller> controller_;
  std::unique_ptr<sim::techno::TechnoExchange> exchange_;
  std::unique_ptr<test::SimTransport> transport_;
  std::unique_ptr<Link> link_;
  TechnoFamily family_;
  ModelPtr model_;
  LinkTiming timing_{50ms, 20ms};
};

TEST(TechnoInterpret, HandshakesAndQueries) {
  EXPECT_EQ(interpret_techno_reply(ack("n7"), "0").status, Reply::Status::ok);
  const auto e = interpret_techno_reply(ack("A1,30"), "7");
  EXPECT_EQ(e.status, Reply::Status::device_error);
  EXPECT_EQ(e.device_code, '7');
  EXPECT_NE(e.text.find("illegal parameters"), std::string::npos);
  const auto p = interpret_techno_reply(query("P"), "000010002000FFFFFE\r");
  EXPECT_EQ(p.status, Reply::Status::ok);
  EXPECT_EQ(p.values, (std::vector<int64_t>{16, 8192, -2}));
  EXPECT_EQ(interpret_techno_reply(query("P"), "4").device_code, '4');
  EXPECT_EQ(interpret_techno_reply(query("P"), "0").status, Reply::Status::garbled);
  // The digits an idle gap ended: a three-axis reply cut short is garbled, not Z = 0.
  EXPECT_EQ(interpret_techno_reply(query("P"), "000010002000").status, Reply::Status::garbled);
  EXPECT_EQ(interpret_techno_reply(query("P"), "000010", 1).values,
            (std::vector<int64_t>{16, 0, 0}));
  EXPECT_EQ(interpret_techno_reply(query("b65531", NumberFormat::hex), "0FF\r").values,
            std::vector<int64_t>{255});
  EXPECT_EQ(interpret_techno_reply(ack("n7"), "x").status, Reply::Status::garbled);
  EXPECT_EQ(interpret_techno_reply(query("n7"), "0").status, Reply::Status::garbled);
}

TEST_F(TechnoBench, AxesNotDefinedUntilTheInitialisationIsSent) {
  auto o = defined();
  o.axes = 0;
  start(o, model_text(", init_when_undefined: false"));
  const auto before = transact(query("P"));
  EXPECT_EQ(before.status, Reply::Status::device_error);
  EXPECT_EQ(before.device_code, '4');
  EXPECT_EQ(transact(ack("7")).status, Reply::Status::ok);
  const auto after = transact(query("P"));
  ASSERT_EQ(after.status, Reply::Status::ok) << after.text;
  // X Y Z, in_motion, X Y Z in units, motion fault and error.
  EXPECT_EQ(after.values, (std::vector<int64_t>{0, 0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(transport_->writes().front(), "@0P\r");
}

TEST_F(TechnoBench, PowerUpStateIsInitialisedAtFirstContact) {
  auto o = defined();
  o.axes = 0;  // as the controller powers up: everything answers 4
  start(o);
  const auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok) << p.text;
  EXPECT_EQ(transport_->writes(), (std::vector<std::string>{"@0P\r", "@07\r", "@0P\r"}));
  const auto notes = link_->take_notes();
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].text.find("at first contact"), std::string::npos) << notes[0].text;
  // A move works at once.
  EXPECT_EQ(transact(ack("M100,5000,0,30,0,30,0,30")).status, Reply::Status::ok);
}

TEST_F(TechnoBench, PowerCycleAfterInitialisationFailsTheMoveButDefinesTheAxes) {
  start(defined());
  ASSERT_EQ(transact(ack("7")).status, Reply::Status::ok);
  controller_->control("power-cycle", {}, sim::SimClock::now());
  const auto r = transact(ack("M100,5000,0,30,0,30,0,30"));
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, '4');
  EXPECT_NE(r.text.find("home before moving"), std::string::npos) << r.text;
  EXPECT_EQ(transport_->writes().back(), "@07\r");
  EXPECT_EQ(transact(ack("M100,5000,0,30,0,30,0,30")).status, Reply::Status::ok);
}

// Issue 49: a card that powered up defined (or was defined before the gateway started) and
// answered a poll was defined; its `4` after a power cycle is a controller reset, not a first
// contact, so the move it interrupted is not taken as arrived.
TEST_F(TechnoBench, PowerCycleOfACardDefinedBeforeTheGatewayIsAReset) {
  start(defined());
  const auto before = transact(query("P"));
  ASSERT_EQ(before.status, Reply::Status::ok) << before.text;
  EXPECT_FALSE(before.controller_reset);
  controller_->control("power-cycle", {}, sim::SimClock::now());
  const auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok) << p.text;
  EXPECT_TRUE(p.controller_reset);
  const auto notes = link_->take_notes();
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes.back().text.find("lost its definition"), std::string::npos) << notes.back().text;
  EXPECT_FALSE(transact(query("P")).controller_reset);  // reported once
  controller_->control("power-cycle", {}, sim::SimClock::now());
  const auto r = transact(ack("M100,5000,0,30,0,30,0,30"));
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_TRUE(r.controller_reset);
  EXPECT_NE(r.text.find("home before moving"), std::string::npos) << r.text;
}

// A card met in its power-up state was not defined before: no reset.
TEST_F(TechnoBench, PowerUpStateAtFirstContactIsNoReset) {
  auto o = defined();
  o.axes = 0;
  start(o);
  const auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok) << p.text;
  EXPECT_FALSE(p.controller_reset);
}

// Issue 26, item 4: the bus reopens the port while the node is offline (a cable pull); the
// controller is power-cycled meanwhile. The definition the family sent before is evidence about
// the controller, not the port: the move is still not repeated in the reset coordinates.
TEST_F(TechnoBench, PowerCycleAfterAPortReopenDoesNotRepeatTheMove) {
  start(defined());
  ASSERT_EQ(transact(ack("7")).status, Reply::Status::ok);
  controller_->control("power-cycle", {}, sim::SimClock::now());
  run(family_.on_link_open(*link_, timing_));
  run(family_.on_link_open(*link_, timing_));
  transport_->clear_writes();
  const auto r = transact(ack("M1500,5000,0,30,0,30,0,30"));
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_NE(r.text.find("home before moving"), std::string::npos) << r.text;
  int moves = 0;
  for (const auto& w : transport_->writes()) moves += w.starts_with("@0M") ? 1 : 0;
  EXPECT_EQ(moves, 1);
}

TEST_F(TechnoBench, CapitalMoveAnswersWhenTheMotionEnds) {
  start(defined());
  ASSERT_EQ(transact(query("P")).status, Reply::Status::ok);
  // 1000 steps at 5000 steps/s, ramps at 100000 steps/s²: 0.2 + 0.05 s.
  const auto budget = family_.reply_budget(device(0), "M1000,5000,0,30,0,30,0,30", timing_);
  EXPECT_EQ(budget, 50ms + 312500us + 150ms);
  const auto t0 = Clock::now();
  const auto r = transact(ack("M1000,5000,0,30,0,30,0,30"));
  const auto took = Clock::now() - t0;
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_GE(took, 240ms);
  EXPECT_LT(took, budget);  // answered by the motion's end, not by the budget running out
  const auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok);
  EXPECT_EQ(p.values, (std::vector<int64_t>{1000, 0, 0, 0, 1000, 0, 0, 0, 0}));
}

TEST_F(TechnoBench, HomingWithoutMechanicsTimesOutAndSendsStopTwice) {
  auto o = defined();
  o.mechanics = false;
  start(o);
  // Travel 1000 at the default home speed 2000: 0.5 + 0.02 s, x1.25, + 150 ms + 50 ms.
  const auto budget = family_.reply_budget(device(0), "R1", timing_);
  const auto t0 = Clock::now();
  const auto r = transact(ack("R1"));
  const auto took = Clock::now() - t0;
  EXPECT_EQ(r.status, Reply::Status::timeout);
  EXPECT_NE(r.text.find("never answers"), std::string::npos) << r.text;
  EXPECT_NE(r.text.find("sent stop"), std::string::npos) << r.text;
  EXPECT_GE(took, 800ms);
  EXPECT_LT(took, 2 * budget);  // one budget and the stops, not a second wait
  EXPECT_EQ(transport_->writes().back(), std::string("\xff\xff"));
  // Both STOPs were needed to leave the homing loop; the controller answers again.
  const auto p = transact(query("P"));
  EXPECT_EQ(p.status, Reply::Status::ok) << p.text;
  EXPECT_EQ(controller_->counters().stops, 2u);
  EXPECT_EQ(controller_->busy(), sim::techno::Controller::Busy::idle);
}

TEST_F(TechnoBench, HomeSpeedsSentWithDShortenTheHomingBudget) {
  start(defined());
  const auto slow = family_.reply_budget(device(0), "R1", timing_);
  ASSERT_EQ(transact(ack("d4000,4000,4000")).status, Reply::Status::ok);
  const auto fast = family_.reply_budget(device(0), "R1", timing_);
  EXPECT_LT(fast, slow);
  const auto r = transact(ack("R7"));
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(transact(query("P")).values[0], 0);
}

TEST_F(TechnoBench, StopGetsThroughWhileAMoveHoldsTheLine) {
  start(defined());
  ASSERT_EQ(transact(query("P")).status, Reply::Status::ok);
  // 5000 steps at 1000 steps/s: five seconds, stopped after 300 ms.
  std::optional<Reply> stop;
  asio::co_spawn(io_, urgent_after(family_, *link_, 300ms, "<stop>"),
                 [&](std::exception_ptr, Reply r) { stop = r; });
  const auto t0 = Clock::now();
  const auto r = transact(ack("A5000,1000,0,30,0,30,0,30"));
  const auto took = Clock::now() - t0;
  ASSERT_TRUE(stop);
  EXPECT_EQ(stop->status, Reply::Status::ok);
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, 0xff);
  EXPECT_NE(r.text.find("ended by stop (0xFF)"), std::string::npos) << r.text;
  // 300 ms, then the stop_settle of 300 ms: well before the five-second move would end.
  EXPECT_LT(took, 2500ms);
  const auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok);
  EXPECT_GT(p.values[0], 100);
  EXPECT_LT(p.values[0], 1000);
  EXPECT_EQ(p.values[3], 1);  // just stopped: in motion until two polls agree
  const auto again = transact(query("P"));
  EXPECT_EQ(again.values[3], 0);
}

TEST_F(TechnoBench, StopAcknowledgedByTheControllerStillEndsTheMoveAsStopped) {
  auto o = defined();
  o.stop_acknowledges = true;
  start(o);
  std::optional<Reply> stop;
  asio::co_spawn(io_, urgent_after(family_, *link_, 200ms, "<stop>"),
                 [&](std::exception_ptr, Reply r) { stop = r; });
  const auto r = transact(ack("A5000,1000,0,30,0,30,0,30"));
  EXPECT_EQ(r.device_code, 0xff);
}

TEST_F(TechnoBench, LowerCaseMoveFreesTheLineAndPollsInferTheEnd) {
  start(defined());
  ASSERT_EQ(transact(query("P")).status, Reply::Status::ok);
  const auto t0 = Clock::now();
  ASSERT_EQ(transact(ack("a1000,2500,0,30,0,30,0,30")).status, Reply::Status::ok);
  EXPECT_LT(Clock::now() - t0, 400ms);  // answered at the start, not after the 0.4 s motion
  const auto moving = transact(query("P"));
  ASSERT_EQ(moving.status, Reply::Status::ok);
  EXPECT_EQ(moving.values[3], 1);
  EXPECT_LT(moving.values[0], 1000);
  int64_t in_motion = 1;
  int64_t x = 0;
  for (int i = 0; i < 40 && in_motion; ++i) {
    std::this_thread::sleep_for(50ms);
    const auto p = transact(query("P"));
    ASSERT_EQ(p.status, Reply::Status::ok);
    in_motion = p.values[3];
    x = p.values[0];
  }
  EXPECT_EQ(in_motion, 0);
  EXPECT_EQ(x, 1000);
  EXPECT_GE(Clock::now() - t0, 400ms);
}

// IT116G against an independent implementation: the limit stops the axis at 600 of 1000 and the
// controller sends `2` after the `0` it gave at the start. The motion ends with that error.
TEST_F(TechnoBench, LimitAfterTheAcknowledgeIsReportedAsTheMotionsError) {
  start(defined());
  ASSERT_EQ(transact(query("P")).status, Reply::Status::ok);
  // Machine coordinates: the axis starts 500 steps from its home switch, where P reads 0.
  controller_->control("limit", std::vector<std::string>{"1100"}, sim::SimClock::now());
  Reply p;
  ASSERT_NO_FATAL_FAILURE(move_to_rest("a1000,2500,0,30,0,30,0,30", 40, &p));
  EXPECT_EQ(p.values[0], 600);
  EXPECT_EQ(p.values[7], 1);
  EXPECT_EQ(p.values[8], '2');
  // A stop after it (the PLC's reaction) does not inherit the error; nor does the next motion.
  ASSERT_EQ(run(family_.send_urgent(*link_, device(0), ack("<stop>"))).status, Reply::Status::ok);
  EXPECT_EQ(transact(query("P")).values[8], 0);
  controller_->control("limit", std::vector<std::string>{"off"}, sim::SimClock::now());
  ASSERT_EQ(transact(ack("a100,2500,0,30,0,30,0,30")).status, Reply::Status::ok);
  EXPECT_EQ(transact(query("P")).values[8], 0);
}

TEST_F(TechnoBench, CapitalMoveIntoTheLimitAnswers2) {
  start(defined());
  controller_->control("limit", std::vector<std::string>{"600"}, sim::SimClock::now());
  const auto r = transact(ack("A1000,2500,0,30,0,30,0,30"));
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, '2');
}

// The first move after initialising: its start position is unknown to the family (no poll in
// between), so the estimate assumes a full travel (20000 steps at 5000 steps/s: 4 s). The move
// itself takes 0.25 s; the polls see the axis at its target long before the estimate.
TEST_F(TechnoBench, LowerCaseMoveEndsWhenThePollsSeeItAtRestNotAtTheEstimate) {
  auto o = defined();
  o.axes = 0;
  start(o, model_text("", 20000));
  ASSERT_EQ(transact(ack("7")).status, Reply::Status::ok);
  const auto t0 = Clock::now();
  Reply p;
  ASSERT_NO_FATAL_FAILURE(move_to_rest("m1000,5000,0,30,0,30,0,30", 100, &p));
  EXPECT_EQ(p.values[0], 1000);
  EXPECT_EQ(p.values[8], 0);
  EXPECT_LT(Clock::now() - t0, 2s);  // half the estimate
}

TEST_F(TechnoBench, HomeEndsWhenTheAxisRestsAtTheSwitch) {
  start(defined(), model_text("", 20000));
  // Estimate: 20000 steps at the home speed 2000 = 10 s; the axis is 500 steps from its switch.
  const auto t0 = Clock::now();
  Reply p;
  ASSERT_NO_FATAL_FAILURE(move_to_rest("r1", 200, &p));
  EXPECT_EQ(p.values[0], 0);
  EXPECT_LT(Clock::now() - t0, 5s);
}

// Issue 12: a controller slower than reply_timeout. Its late `0` must never confirm the next
// command, which the controller refuses (`7`).
TEST_F(TechnoBench, LateHandshakeNeverAnswersTheNextCommand) {
  for (const uint32_t baud : {0u, 9600u, 115200u}) {
    const bool wire = baud != 0;
    sim::techno::ExchangeOptions x;
    if (wire) {
      x.wire.enabled = true;
      x.wire.timing = sim::WireTiming(baud);
      x.wire.turnaround = 1ms;
    }
    start(defined(), model_text(), x);
    faults_.reply_delay = 70ms;  // reply_timeout is 50 ms
    int confirmed_refusals = 0;
    for (int i = 0; i < 10; ++i) {
      transact(ack("n7"));
      const auto refused = transact(ack("e3"));
      if (refused.status == Reply::Status::ok) ++confirmed_refusals;
      const auto p = transact(query("P"));
      if (p.status == Reply::Status::ok) {
        EXPECT_EQ(p.values[0], 0);
      }
    }
    EXPECT_EQ(confirmed_refusals, 0) << baud << " baud (0: no wire time)";
    faults_.reply_delay = 0ms;
    EXPECT_EQ(transact(ack("e3")).device_code, '7');
    EXPECT_EQ(transact(ack("n7")).status, Reply::Status::ok);
  }
}

TEST_F(TechnoBench, AHandshakeFollowedByMoreBytesIsGarbled) {
  start(defined());
  faults_.reply_delay = 70ms;
  transact(query("P"));  // times out; its 18 digits come late
  faults_.reply_delay = 0ms;
  // Without the guard the `0` of this command and the late digits would share the line.
  const auto r = transact(ack("n7"));
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(interpret_techno_reply(ack("n7"), "0").status, Reply::Status::ok);
}

// A lower-case move answers at its start; the `P` the family sends right after it is answered
// at once by a controller that answers during motions, and only at the motion's end by one that
// buffers it (p.73). Either way the step's reply says where the motion stands: under the second
// reading the step lasts the motion (a model's confirm_after then holds the line, so the axis
// reads as moving), and the first poll after it finds the axis at rest at its target.
class TechnoQueryReadings : public TechnoBench, public ::testing::WithParamInterface<bool> {};

TEST_P(TechnoQueryReadings, QueriesDeferredDuringMotionWaitForItsEnd) {
  const bool live = GetParam();
  auto o = defined();
  o.queries_during_motion = live;
  start(o);
  ASSERT_EQ(transact(query("P")).status, Reply::Status::ok);
  const auto t0 = Clock::now();
  const auto moved = transact(ack("a1000,2500,0,30,0,30,0,30"));  // 0.4 s
  ASSERT_EQ(moved.status, Reply::Status::ok) << moved.text;
  if (live)
    EXPECT_LT(Clock::now() - t0, 300ms);
  else
    EXPECT_GE(Clock::now() - t0, 300ms);
  const auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok) << p.text;
  if (live) {
    EXPECT_EQ(p.values[3], 1);
  } else {
    EXPECT_EQ(p.values[0], 1000);
    EXPECT_EQ(p.values[3], 0);
  }
}

INSTANTIATE_TEST_SUITE_P(Techno, TechnoQueryReadings, ::testing::Bool());

// STOP during a lower-case move whose position query the controller holds: the stop goes out,
// the held query is answered when the ramp has ended, and the move reports that it was stopped.
TEST_F(TechnoBench, StopEndsALowerCaseMoveWhoseQueryIsHeld) {
  auto o = defined();
  o.queries_during_motion = false;
  start(o);
  ASSERT_EQ(transact(query("P")).status, Reply::Status::ok);
  std::optional<Reply> stop;
  asio::co_spawn(io_, urgent_after(family_, *link_, 150ms, "<stop>"),
                 [&](std::exception_ptr, Reply r) { stop = r; });
  const auto moved = transact(ack("a5000,1000,0,30,0,30,0,30"));  // 5 s without the stop
  ASSERT_TRUE(stop);
  EXPECT_EQ(stop->status, Reply::Status::ok);
  EXPECT_EQ(moved.device_code, 0xff) << moved.text;
  Reply p;
  for (int i = 0; i < 20; ++i) {
    p = transact(query("P"));
    ASSERT_EQ(p.status, Reply::Status::ok) << p.text;
    if (p.values[3] == 0) break;
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_EQ(p.values[3], 0);
  EXPECT_GT(p.values[0], 0);
  EXPECT_LT(p.values[0], 1000);
  EXPECT_EQ(p.values[8], 0);  // stopped, not short of a target
}

TEST_F(TechnoBench, PositionReplyWithHandshakeAndNoTerminator) {
  auto o = defined();
  o.position_ack = true;
  o.reply_cr = false;
  start(o);
  const auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok) << p.text;
  EXPECT_EQ(p.values[0], 0);
}

TEST_F(TechnoBench, BarePositionReplyWithoutTerminatorEndsAtTheGap) {
  auto o = defined();
  o.reply_cr = false;
  start(o);
  const auto t0 = Clock::now();
  ASSERT_EQ(transact(query("P")).status, Reply::Status::ok);
  EXPECT_GE(Clock::now() - t0, 20ms);  // one byte_timeout
}

// Bare mode knows the length, but a CR may still follow the digits under another reading: the
// reply is read until the byte gap (tests/families/techno_c/techno_reply_cr_test.cpp).
TEST_F(TechnoBench, BareModeReadsTheDigitsWithoutATerminator) {
  auto o = defined();
  o.reply_cr = false;
  start(o, model_text(", position_reply: bare"));
  const auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok) << p.text;
  EXPECT_EQ(p.values[0], 0);
}

TEST_F(TechnoBench, ErrorCharactersBecomeDeviceErrorsWithTheirCode) {
  start(defined());
  const struct {
    const char* command;
    char code;
  } cases[] = {
      {"A1,30", '7'}, {"d10,10,10", 'D'}, {"R9", '3'}, {"x1", '5'}, {"A1,30,0,30,0,30,0,20", 'D'},
      {"e3", '7'}};
  for (const auto& c : cases) {
    const auto r = transact(ack(c.command));
    EXPECT_EQ(r.status, Reply::Status::device_error) << c.command;
    EXPECT_EQ(r.device_code, static_cast<unsigned char>(c.code)) << c.command << ": " << r.text;
  }
}

TEST_F(TechnoBench, OutsideTheReachAnswers2) {
  start(defined());
  const auto r = transact(ack("M-1000,1000,0,30,0,30,0,30"));  // behind the home switch
  EXPECT_EQ(r.device_code, '2');
}

TEST_F(TechnoBench, BusWideAddressedCommandIsRefusedWithoutSending) {
  start(defined());
  Request r = ack("n7");
  r.bus_wide = true;
  EXPECT_EQ(transact(r).status, Reply::Status::device_error);
  EXPECT_TRUE(transport_->writes().empty());
  Request stop = ack("<stop>");
  stop.bus_wide = true;
  EXPECT_EQ(transact(stop).status, Reply::Status::ok);
  EXPECT_EQ(transport_->all_written(), std::string("\xff\xff"));
}

TEST_F(TechnoBench, UrgentRefusesAddressedCommands) {
  start(defined());
  const auto r = run(family_.send_urgent(*link_, device(0), ack("n7")));
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_TRUE(transport_->writes().empty());
}

TEST_F(TechnoBench, InitOnConnectSendsTheAxesDefinitionFirstAfterEveryOpen) {
  auto o = defined();
  o.axes = 0;
  start(o, model_text(", init_on_connect: true"));
  ASSERT_EQ(transact(query("P")).status, Reply::Status::ok);
  ASSERT_EQ(transport_->writes().size(), 2u);
  EXPECT_EQ(transport_->writes()[0], "@07\r");
  EXPECT_EQ(transact(query("P")).status, Reply::Status::ok);
  EXPECT_EQ(transport_->writes().size(), 3u);
  run(family_.on_link_open(*link_, timing_));
  EXPECT_EQ(transact(query("P")).status, Reply::Status::ok);
  EXPECT_EQ(transport_->writes()[3], "@07\r");
}

TEST_F(TechnoBench, AnotherDeviceNumberIsSilence) {
  start(defined());
  const auto r = transact(query("P"), 3);
  EXPECT_EQ(r.status, Reply::Status::timeout);
  EXPECT_EQ(transport_->writes().front(), "@3P\r");
  EXPECT_EQ(controller_->counters().other_device, 1u);
}

TEST_F(TechnoBench, GarbledAndTruncatedReplies) {
  start(defined());
  faults_.truncated_replies = 1;
  const auto t = transact(query("P"));
  EXPECT_EQ(t.status, Reply::Status::garbled) << t.text;
  faults_.silence = true;
  EXPECT_EQ(transact(ack("n7")).status, Reply::Status::timeout);
}

// The manual leaves open whether `@0P` answers with the `0` handshake first, whether a CR ends
// it, and whether a capital command ended by STOP still answers. The core scenario (power-up,
// positions, a capital move, a lower-case move, a stop) runs under every combination.
class TechnoReadings : public TechnoBench,
                       public ::testing::WithParamInterface<std::tuple<bool, bool, bool>> {};

TEST_P(TechnoReadings, CoreScenario) {
  const auto [position_ack, reply_cr, stop_acknowledges] = GetParam();
  auto o = defined();
  o.axes = 0;  // power-up state
  o.position_ack = position_ack;
  o.reply_cr = reply_cr;
  o.stop_acknowledges = stop_acknowledges;
  start(o, model_text("", 1000, "2s"));  // a margin a loaded machine cannot exceed
  const auto first = transact(query("P"));
  ASSERT_EQ(first.status, Reply::Status::ok) << first.text;
  EXPECT_EQ(first.values[0], 0);
  const auto moved = transact(ack("M800,5000,300,5000,0,30,0,30"));
  ASSERT_EQ(moved.status, Reply::Status::ok) << moved.text;
  auto p = transact(query("P"));
  ASSERT_EQ(p.status, Reply::Status::ok) << p.text;
  EXPECT_EQ(p.values[0], 800);
  EXPECT_EQ(p.values[1], 300);
  EXPECT_EQ(p.values[3], 0);
  ASSERT_NO_FATAL_FAILURE(move_to_rest("a200,2500,0,30,0,30,0,30", 40, &p));
  EXPECT_EQ(p.values[0], 1000);
  EXPECT_EQ(p.values[8], 0);
  // A long capital move ended by STOP: reported as stopped (255) whether or not it answers.
  std::optional<Reply> stop;
  asio::co_spawn(io_, urgent_after(family_, *link_, 200ms, "<stop>"),
                 [&](std::exception_ptr, Reply r) { stop = r; });
  const auto stopped = transact(ack("A5000,1000,0,30,0,30,0,30"));
  EXPECT_EQ(stopped.device_code, 0xff) << stopped.text;
  // The line is clean afterwards.
  for (int i = 0; i < 3; ++i) EXPECT_EQ(transact(query("P")).status, Reply::Status::ok);
  EXPECT_EQ(transact(ack("n7")).status, Reply::Status::ok);
}

INSTANTIATE_TEST_SUITE_P(Techno, TechnoReadings,
                         ::testing::Combine(::testing::Bool(), ::testing::Bool(),
                                            ::testing::Bool()));

TEST(TechnoFamilyBasics, AddressesAndWireEstimate) {
  TechnoFamily f;
  std::string error;
  const auto a = f.parse_address("0", error);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->text, "0");
  EXPECT_FALSE(f.parse_address("12", error));
  EXPECT_EQ(f.estimate_wire_chars(device(0), query("P")), 4u + 20u);
  EXPECT_EQ(f.estimate_wire_chars(device(0), ack("n7")), 5u + 1u);
}

}  // namespace
}  // namespace fieldgate
