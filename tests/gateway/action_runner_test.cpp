// ActionRunner's early confirmation (confirm_after) against a bus whose queue holds the command:
// the patience counts from the moment the command goes on the wire, so a move still waiting
// behind a slow poll is not reported as running (a stop sent then would reach the controller
// before the move).
#include <gtest/gtest.h>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <optional>

#include "gateway/bus/bus.hpp"
#include "gateway/bus/wire_trace.hpp"
#include "gateway/register_map/action_runner.hpp"
#include "mapping/model_loader.hpp"
#include "scripted_bus.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
namespace asio = boost::asio;

// Holds each command in its queue until send(), then in flight until answer().
class QueueingBus : public Bus {
 public:
  explicit QueueingBus(asio::any_io_executor executor)
      : send_(executor, SteadyTime::max()), answer_(executor, SteadyTime::max()), trace_("test") {}

  void send() {
    may_send_ = true;
    send_.cancel();
  }
  void answer() {
    may_answer_ = true;
    answer_.cancel();
  }
  bool sent() const { return sent_; }

  asio::awaitable<void> run() override { co_return; }
  void stop() override {}
  asio::awaitable<Reply> submit(int, Request, CommandOptions options) override {
    while (!may_send_) co_await send_.async_wait(asio::as_tuple(asio::use_awaitable));
    sent_ = true;
    if (options.on_sent) options.on_sent();
    while (!may_answer_) co_await answer_.async_wait(asio::as_tuple(asio::use_awaitable));
    Reply reply;
    reply.status = Reply::Status::ok;
    co_return reply;
  }
  const BusConfig& config() const override { return config_; }
  const BusCounters& counters() const override { return counters_; }
  WireTrace& trace() override { return trace_; }
  const NodeConfig& node_config(int) const override { return node_; }
  std::vector<std::shared_ptr<NodeImage>> node_images() const override { return {}; }
  void rebind(int, NodeUpdated) override {}
  int first_node_index() const override { return 0; }

 private:
  asio::steady_timer send_, answer_;
  bool may_send_ = false, may_answer_ = false, sent_ = false;
  BusConfig config_;
  BusCounters counters_;
  WireTrace trace_;
  NodeConfig node_;
};

TEST(ActionRunnerEarlyConfirmation, PatienceCountsFromTheWireNotFromTheQueue) {
  Diagnostics d;
  const ModelPtr model = load_model_text(R"(model: m
family: techno-c
actions:
  move:
    code: 1
    steps:
      - {send: "M100,2000", confirm_after: 20ms}
)",
                                         "m.yaml", d);
  ASSERT_TRUE(model) << d.to_text();
  asio::io_context io;
  QueueingBus bus(io.get_executor());
  ProcessImage image({std::make_shared<NodeImage>()});
  ActionRunner runner(io.get_executor(), image, [&](int) -> Bus& { return bus; });
  bool confirmed = false, sent_when_confirmed = false;
  Reply reply;
  asio::co_spawn(
      io,
      [&]() -> asio::awaitable<void> {
        reply = co_await runner.start(0, model, model->actions.front());
        sent_when_confirmed = bus.sent();
        confirmed = true;
      },
      asio::detached);
  // Queued for ten times the patience: not confirmed, the line is not held.
  io.run_for(200ms);
  EXPECT_FALSE(confirmed);
  EXPECT_FALSE(image.node(0).action.holding_line);
  EXPECT_EQ(image.node(0).action.status, ActionStatus::busy);
  // On the wire and no reply within the patience: confirmed, and the move holds the line.
  bus.send();
  for (int i = 0; i < 100 && !confirmed; ++i) io.run_for(10ms);
  ASSERT_TRUE(confirmed);
  EXPECT_TRUE(sent_when_confirmed);
  EXPECT_EQ(reply.status, Reply::Status::ok);
  EXPECT_TRUE(image.node(0).action.holding_line);
  // The handshake at the end of the motion ends the action.
  bus.answer();
  for (int i = 0; i < 100 && image.node(0).action.status == ActionStatus::busy; ++i)
    io.run_for(10ms);
  EXPECT_EQ(image.node(0).action.status, ActionStatus::done);
  EXPECT_FALSE(image.node(0).action.holding_line);
  runner.stop();
}

class ActionRunnerAcrossAReload : public ::testing::Test {
 protected:
  void SetUp() override {
    Diagnostics d;
    model_ = load_model_text(R"(model: m
family: techno-c
actions:
  home:
    code: 1
    steps:
      - {send: "@0R1"}
      - {delay: 50ms}
      - {send: "@0R2"}
)",
                             "m.yaml", d);
    ASSERT_TRUE(model_) << d.to_text();
    runner_.emplace(io_.get_executor(), image_, [&](int) -> Bus& { return bus_; });
    asio::co_spawn(
        io_,
        [&]() -> asio::awaitable<void> {
          reply_ = co_await runner_->start(1, model_, model_->actions.front());
        },
        asio::detached);
    io_.run_for(10ms);
    ASSERT_EQ(bus_.sent_to, std::vector<int>{1});
  }
  void TearDown() override { runner_->stop(); }
  // Until the action ends (its second step comes after a 50 ms delay).
  void run_action() {
    for (int i = 0; i < 500 && image_.node(1).action.status == ActionStatus::busy; ++i)
      io_.run_for(10ms);
  }

  asio::io_context io_;
  std::shared_ptr<NodeImage> a_ = std::make_shared<NodeImage>(), b_ = std::make_shared<NodeImage>();
  ProcessImage image_{{a_, b_}};
  test::ScriptedBus bus_{{a_, b_}};
  ModelPtr model_;
  std::optional<ActionRunner> runner_;
  std::optional<Reply> reply_;
};

// Found by reading, with issue 31's in-place reload: an action's later step went to the node
// number its first step had, whatever a reload had made of it since.
TEST_F(ActionRunnerAcrossAReload, ALaterStepGoesToTheNodeWhereverTheReloadPutIt) {
  bus_.reload({std::make_shared<NodeImage>(), a_, b_});
  run_action();
  EXPECT_EQ(bus_.sent_to, (std::vector<int>{1, 2}));
  EXPECT_EQ(image_.node(1).action.status, ActionStatus::done);
}

TEST_F(ActionRunnerAcrossAReload, ALaterStepForANodeTheReloadTookAwayFailsUnsent) {
  bus_.reload({a_});
  run_action();
  EXPECT_EQ(bus_.sent_to, std::vector<int>{1});
  EXPECT_EQ(image_.node(1).action.status, ActionStatus::error);
}

// Issue 49: two axes of one node commanded in the same scan. Each action runs with the values
// it was started with, and its steps go out back to back.
class ActionRunnerOnOneNode : public ::testing::Test {
 protected:
  void SetUp() override {
    Diagnostics d;
    model_ = load_model_text(R"(model: m
family: techno-c
poll_classes: {fast: 100ms}
points:
  py: {type: int32, read: "@0P", poll: fast}
setpoints:
  tx: {type: int32}
  ty: {type: int32}
actions:
  setup_and_begin:
    code: 1
    steps:
      - "S{tx}"
      - {delay: 30ms}
      - "B{tx},{ty}"
  other:
    code: 2
    steps: ["O{tx},{ty}"]
  stop:
    code: 3
    steps: [{send: "!", urgent: true}]
)",
                             "m.yaml", d);
    ASSERT_TRUE(model_) << d.to_text();
    node_->setpoints = {0, 0};
    node_->points = {PointValue{}};
    runner_.emplace(io_.get_executor(), image_, [&](int) -> Bus& { return bus_; });
  }
  void TearDown() override { runner_->stop(); }
  void start(const char* name, std::optional<ActionArguments> arguments,
             std::shared_ptr<ActionState> slot) {
    asio::co_spawn(
        io_,
        [this, name, arguments, slot]() -> asio::awaitable<void> {
          co_await runner_->start(0, model_, *model_->find_action(std::string(name)), slot,
                                  arguments);
        },
        asio::detached);
  }
  // Until the action ended (done or error), at most 1.5 s.
  void run_until_idle(const std::shared_ptr<ActionState>& slot) {
    for (int i = 0; i < 300; ++i) {
      io_.restart();
      io_.run_for(5ms);
      if (slot->status == ActionStatus::done || slot->status == ActionStatus::error) return;
    }
  }

  asio::io_context io_;
  std::shared_ptr<NodeImage> node_ = std::make_shared<NodeImage>();
  ProcessImage image_{{node_}};
  test::ScriptedBus bus_{{node_}};
  ModelPtr model_;
  std::optional<ActionRunner> runner_;
};

TEST_F(ActionRunnerOnOneNode, AnActionSendsTheValuesItWasStartedWith) {
  const auto x = std::make_shared<ActionState>();
  start("setup_and_begin", ActionArguments{{511, 0}, {}, {}}, x);
  io_.run_for(5ms);
  // A later write of the node's setpoints (another axis, the native map) changes nothing.
  node_->setpoints = {7, 7};
  run_until_idle(x);
  EXPECT_EQ(bus_.sent, (std::vector<std::string>{"S511", "B511,0"}));
  EXPECT_EQ(x->status, ActionStatus::done);
}

TEST_F(ActionRunnerOnOneNode, AnotherActionsStepsWaitUntilTheFirstActionsStepsAreOut) {
  const auto x = std::make_shared<ActionState>(), y = std::make_shared<ActionState>();
  start("setup_and_begin", ActionArguments{{511, 0}, {}, {}}, x);
  start("other", ActionArguments{{0, 2022}, {}, {}}, y);
  run_until_idle(x);
  run_until_idle(y);
  EXPECT_EQ(bus_.sent, (std::vector<std::string>{"S511", "B511,0", "O0,2022"}));
  EXPECT_EQ(x->status, ActionStatus::done);
  EXPECT_EQ(y->status, ActionStatus::done);
}

// Without the turn the check above is not vacuous: a stop (urgent steps only) takes none and goes
// out between the first action's steps.
TEST_F(ActionRunnerOnOneNode, AnUrgentStopDoesNotWaitForTheTurn) {
  const auto x = std::make_shared<ActionState>(), s = std::make_shared<ActionState>();
  start("setup_and_begin", ActionArguments{{1, 2}, {}, {}}, x);
  start("stop", std::nullopt, s);
  run_until_idle(x);
  ASSERT_EQ(bus_.sent.size(), 3u);
  EXPECT_EQ(bus_.sent[0], "S1");
  EXPECT_EQ(bus_.sent[2], "B1,2");
}

TEST_F(ActionRunnerOnOneNode, AHeldValueIsReadAfterThePreviousActionLetGo) {
  node_->points[0] = {100, std::chrono::steady_clock::now(), true};  // before the first action
  const auto x = std::make_shared<ActionState>(), y = std::make_shared<ActionState>();
  start("setup_and_begin", ActionArguments{{1, 2}, {}, {}}, x);
  start("other", ActionArguments{{9, 0}, {{1, 0}}, {}}, y);
  run_until_idle(x);
  io_.run_for(50ms);
  // The first action is through; the second waits for a reading of py after it.
  EXPECT_EQ(bus_.sent.size(), 2u);
  EXPECT_EQ(y->status, ActionStatus::busy);
  node_->points[0] = {2022, std::chrono::steady_clock::now(), true};
  runner_->node_updated(0);
  run_until_idle(y);
  ASSERT_EQ(bus_.sent.size(), 3u);
  EXPECT_EQ(bus_.sent[2], "O9,2022");
}

TEST_F(ActionRunnerOnOneNode, AHeldValueThatIsNeverReadAgainFailsTheActionUnsent) {
  node_->points[0] = {100, std::chrono::steady_clock::now(), true};
  const auto x = std::make_shared<ActionState>(), y = std::make_shared<ActionState>();
  start("setup_and_begin", ActionArguments{{1, 2}, {}, {}}, x);
  start("other", ActionArguments{{9, 0}, {{1, 0}}, {}}, y);
  for (int i = 0; i < 700 && y->status != ActionStatus::error; ++i) {
    io_.restart();
    io_.run_for(10ms);
  }
  EXPECT_EQ(bus_.sent.size(), 2u);
  EXPECT_EQ(y->status, ActionStatus::error);
  EXPECT_EQ(y->error, kActionErrorUnreachable);
}

TEST(ActionRunnerWatch, AControllerResetWhileTheActionRunsFailsIt) {
  Diagnostics d;
  const ModelPtr model = load_model_text(R"(model: m
family: techno-c
poll_classes: {fast: 10ms}
points:
  moving: {type: int32, read: "@0P", poll: fast}
actions:
  move:
    code: 1
    steps: ["M1"]
    done: {point: moving, equals: 0}
)",
                                         "m.yaml", d);
  ASSERT_TRUE(model) << d.to_text();
  asio::io_context io;
  auto node = std::make_shared<NodeImage>();
  node->points = {PointValue{1, std::chrono::steady_clock::now(), true}};
  ProcessImage image({node});
  test::ScriptedBus bus({node});
  ActionRunner runner(io.get_executor(), image, [&](int) -> Bus& { return bus; });
  asio::co_spawn(
      io, [&]() -> asio::awaitable<void> { co_await runner.start(0, model, model->actions[0]); },
      asio::detached);
  io.run_for(20ms);
  ASSERT_EQ(node->action.status, ActionStatus::busy);
  ++node->controller_resets;  // the unit signed on again: it forgot the move
  node->points[0] = {0, std::chrono::steady_clock::now(), true};  // and stands still
  runner.node_updated(0);
  io.run_for(20ms);
  EXPECT_EQ(node->action.status, ActionStatus::error);
  EXPECT_EQ(node->action.error, kActionErrorControllerReset);
  runner.stop();
}

// Issue 50: a list of failed conditions (motor off or limit stop). Any one ends the action, with
// the error code of the first that holds.
class ActionRunnerFailedList : public ::testing::Test {
 protected:
  void SetUp() override {
    Diagnostics d;
    model_ = load_model_text(R"(model: m
family: techno-c
poll_classes: {fast: 10ms}
points:
  moving: {type: int32, read: "@0M", poll: fast}
  enabled: {type: int32, read: "@0E", poll: fast}
  limits: {type: int32, read: "@0L", poll: fast, bits: {stop: 2}}
  fault_code: {type: int32, read: "@0F", poll: fast}
  limit_code: {type: int32, read: "@0C", poll: fast}
actions:
  move:
    code: 1
    steps: ["M1"]
    done: {point: moving, equals: 0}
    failed:
      - {point: enabled, equals: 0, error_from: fault_code}
      - {point: limits, bit: stop, equals: 1, error_from: limit_code}
)",
                             "m.yaml", d);
    ASSERT_TRUE(model_) << d.to_text();
    set({1, 1, 0, 0, 0});
    runner_.emplace(io_.get_executor(), image_, [&](int) -> Bus& { return bus_; });
    asio::co_spawn(
        io_,
        [&]() -> asio::awaitable<void> { co_await runner_->start(0, model_, model_->actions[0]); },
        asio::detached);
    io_.run_for(20ms);
    ASSERT_EQ(node_->action.status, ActionStatus::busy);
  }
  void TearDown() override { runner_->stop(); }
  // Every point (moving, enabled, limits, fault_code, limit_code) read now.
  void set(const std::vector<int64_t>& values) {
    node_->points.clear();
    for (const int64_t v : values)
      node_->points.push_back(PointValue{v, std::chrono::steady_clock::now(), true});
  }
  // A poll the runner is told of.
  void poll(const std::vector<int64_t>& values) {
    set(values);
    runner_->node_updated(0);
    io_.run_for(20ms);
  }

  asio::io_context io_;
  std::shared_ptr<NodeImage> node_ = std::make_shared<NodeImage>();
  ProcessImage image_{{node_}};
  test::ScriptedBus bus_{{node_}};
  ModelPtr model_;
  std::optional<ActionRunner> runner_;
};

TEST_F(ActionRunnerFailedList, TheSecondConditionEndsTheActionWithItsOwnCode) {
  // Still enabled, still moving: the limit stop (bit 2) alone ends it, with limit_code's 0x42
  // and not fault_code's 7.
  poll({1, 1, 0b100, 7, 0x42});
  EXPECT_EQ(node_->action.status, ActionStatus::error);
  EXPECT_EQ(node_->action.error, 0x42);
}

TEST_F(ActionRunnerFailedList, WhenBothHoldTheFirstGivesTheCode) {
  poll({1, 0, 0b100, 7, 0x42});
  EXPECT_EQ(node_->action.status, ActionStatus::error);
  EXPECT_EQ(node_->action.error, 7);
}

TEST_F(ActionRunnerFailedList, WhenNeitherHoldsDoneWins) {
  poll({1, 1, 0b011, 7, 0x42});
  EXPECT_EQ(node_->action.status, ActionStatus::busy);
  poll({0, 1, 0b011, 7, 0x42});
  poll({0, 1, 0b011, 7, 0x42});
  EXPECT_EQ(node_->action.status, ActionStatus::done);
}

}  // namespace
}  // namespace fieldgate
