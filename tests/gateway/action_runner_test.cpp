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

}  // namespace
}  // namespace fieldgate
