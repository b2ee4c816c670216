// Issue 49, "done means arrived", on the axis profile of a three-axis Techno C142 over a bus that
// answers every command at once: the axes of one node commanded in the same scan each send their
// own target, and a move is done only on a position read after it at its target, with no reset
// of the controller since it was accepted.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>

#include <algorithm>

#include "control_table_test.hpp"
#include "gateway/register_map/axis_profile_server.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
namespace asio = boost::asio;
namespace ap = axis_profile;

class AxisProfileDone : public test::ControlTableTest {
 protected:
  void SetUp() override {
    ConfigFileTest::SetUp();
    start_control();
    server_ =
        std::make_unique<AxisProfileServer>(image_, *actions_, *control_, config_->gateway.modbus);
    // The controller as the first polls found it: every axis at 0, standing still.
    image_.node(0).state = NodeState::online;
    for (const char* p :
         {"position_x", "position_y", "position_z", "in_motion", "motion_fault", "motion_error"})
      poll(p, 0);
  }
  void TearDown() override {
    server_.reset();
    ControlTableTest::TearDown();
  }

  ProfileUnit axis(int index) const {
    const auto& node = config_->gateway.buses[0].nodes[0];
    return ProfileUnit{0, &node, node.model, index};
  }
  // A fresh reading of a point, as a poll brings it: the poll's reply (the controller's `P`)
  // refreshes every point of its class, the others with their values as they were.
  void poll(const std::string& name, int64_t value) {
    const PointDef* point = model().find_point(name);
    const auto now = std::chrono::steady_clock::now();
    auto& points = image_.node(0).points;
    for (std::size_t i = 0; i < model().points.size(); ++i)
      if (model().points[i].poll_class == point->poll_class) {
        points[i].updated = now;
        points[i].valid = true;
      }
    points[static_cast<std::size_t>(point - model().points.data())].value = value;
    actions_->node_updated(0);
  }
  // The PLC's writes of the target (holding 0-1) and then of command and sequence (holding
  // 8-9); velocity and the rest stay as the model's defaults.
  // A command whose first action fails at once is answered with an exception (`refused`).
  void command(int axis_index, int64_t target, ProfileCommand c, uint16_t sequence,
               bool refused = false) {
    asio::co_spawn(
        io_,
        [this, axis_index, target, c, sequence, refused]() -> asio::awaitable<void> {
          const uint16_t position[2] = {static_cast<uint16_t>((target >> 16) & 0xffff),
                                        static_cast<uint16_t>(target & 0xffff)};
          const uint16_t handshake[2] = {static_cast<uint16_t>(c), sequence};
          auto result = co_await server_->write(axis(axis_index), ap::target_position, position,
                                                WordOrder::high_first);
          EXPECT_TRUE(result.ok()) << "exception " << static_cast<int>(result.exception());
          result = co_await server_->write(axis(axis_index), ap::command_code, handshake,
                                           WordOrder::high_first);
          EXPECT_EQ(result.ok(), !refused);
        },
        asio::detached);
  }
  void run(std::chrono::milliseconds how_long) {
    io_.run_for(how_long);
    io_.restart();
  }
  // Runs until `done` holds, for at most 3 s (a loaded machine runs the loop late, not wrong).
  template <class Done>
  void run_until(Done done) {
    for (int i = 0; i < 300 && !done(); ++i) run(10ms);
  }
  uint16_t input(int axis_index, uint16_t address) {
    const auto r = server_->read(axis(axis_index), modbus::RegisterTable::input_registers, address,
                                 1, WordOrder::high_first);
    return r.ok() ? r.values().front() : 0xdead;
  }
  CommandStatus status(int axis_index) {
    return static_cast<CommandStatus>(input(axis_index, ap::command_status));
  }
  bool ended(int axis_index) {
    const CommandStatus s = status(axis_index);
    return s == CommandStatus::done || s == CommandStatus::error || s == CommandStatus::aborted;
  }
  std::vector<std::string> moves() const {
    std::vector<std::string> m;
    std::copy_if(bus_.sent.begin(), bus_.sent.end(), std::back_inserter(m),
                 [](const std::string& s) { return !s.empty() && s.front() == 'M'; });
    return m;
  }

  std::unique_ptr<AxisProfileServer> server_;
};

TEST_F(AxisProfileDone, TwoAxesCommandedInOneScanEachSendTheirOwnTarget) {
  command(0, 511, ProfileCommand::move_absolute, 1);
  command(1, 2022, ProfileCommand::move_absolute, 1);
  run_until([&] { return !moves().empty(); });
  run(50ms);
  // X's move went out with X's target and Y where it stood; Y's waits for a reading of X taken
  // after X's move (it names every axis).
  ASSERT_EQ(moves().size(), 1u) << ::testing::PrintToString(bus_.sent);
  EXPECT_EQ(moves()[0], "M511,2000,0,2000,0,2000,0,2000");
  poll("position_x", 511);
  run_until([&] { return moves().size() == 2; });
  ASSERT_EQ(moves().size(), 2u) << ::testing::PrintToString(bus_.sent);
  EXPECT_EQ(moves()[1], "M511,2000,2022,2000,0,2000,0,2000");
  // The polls after both moves: standing still, each axis at its own target.
  for (int i = 0; i < 60 && (status(0) != CommandStatus::done || status(1) != CommandStatus::done);
       ++i) {
    poll("position_y", 2022);
    poll("in_motion", 0);
    run(50ms);
  }
  EXPECT_EQ(status(0), CommandStatus::done);
  EXPECT_EQ(status(1), CommandStatus::done);
}

TEST_F(AxisProfileDone, AnAxisThatStopsAwayFromItsTargetEndsFailedNotDone) {
  command(0, 511, ProfileCommand::move_absolute, 1);
  run_until([&] { return !moves().empty(); });
  ASSERT_EQ(moves().size(), 1u);
  // Standing still where it started: the controller never ran the move to its end.
  for (int i = 0; i < 40 && status(0) == CommandStatus::busy; ++i) {
    poll("in_motion", 0);
    poll("position_x", 0);
    run(100ms);
  }
  EXPECT_EQ(status(0), CommandStatus::error);
  EXPECT_EQ(input(0, ap::command_error), kProfileErrorNotAtTarget);
  EXPECT_EQ(static_cast<PlcopenState>(input(0, ap::plcopen_state)), PlcopenState::error_stop);
}

TEST_F(AxisProfileDone, ADoneNeedsAPositionReadAfterTheMove) {
  poll("position_x", 511);  // already there before the move: no proof of this command
  command(0, 511, ProfileCommand::move_absolute, 1);
  run(200ms);
  EXPECT_EQ(status(0), CommandStatus::busy);
  for (int i = 0; i < 60 && status(0) != CommandStatus::done; ++i) {
    poll("position_x", 511);
    run(50ms);
  }
  EXPECT_EQ(status(0), CommandStatus::done);
}

TEST_F(AxisProfileDone, AControllerResetDuringTheMoveEndsItFailed) {
  command(0, 511, ProfileCommand::move_absolute, 1);
  poll("in_motion", 1);
  run(50ms);
  ASSERT_EQ(status(0), CommandStatus::busy);
  ++image_.node(0).controller_resets;
  poll("position_x", 511);  // even at the target: the reset makes nothing of the move provable
  poll("in_motion", 0);
  run_until([&] { return status(0) != CommandStatus::busy; });
  EXPECT_EQ(status(0), CommandStatus::error);
  EXPECT_EQ(input(0, ap::command_error), kActionErrorControllerReset);
}

// A Techno card power-cycled during a capital M never acknowledges it: the step gets no reply.
// The card's next answer (a poll meets its `4`) shows the reset, which is why the move failed.
TEST_F(AxisProfileDone, AMoveCutShortBySilenceEndsWithTheResetItsNextAnswerShows) {
  bus_.replies = {Reply::of(Reply::Status::ok), Reply::of(Reply::Status::timeout, "no handshake")};
  command(0, 511, ProfileCommand::move_absolute, 1, true);
  run(300ms);
  ASSERT_EQ(moves().size(), 1u);
  EXPECT_EQ(status(0), CommandStatus::busy);  // waiting for the controller's next answer
  ++image_.node(0).controller_resets;
  poll("position_x", 0);
  run_until([&] { return ended(0); });
  EXPECT_EQ(status(0), CommandStatus::error);
  EXPECT_EQ(input(0, ap::command_error), kActionErrorControllerReset);
}

// Silence with no reset behind it keeps its own code, once the axis was read again.
TEST_F(AxisProfileDone, AMoveWithNoReplyAndNoResetEndsNoReply) {
  bus_.replies = {Reply::of(Reply::Status::ok), Reply::of(Reply::Status::timeout, "no handshake")};
  command(0, 511, ProfileCommand::move_absolute, 1, true);
  run(300ms);
  poll("position_x", 0);
  run_until([&] { return ended(0); });
  EXPECT_EQ(status(0), CommandStatus::error);
  EXPECT_EQ(input(0, ap::command_error), kActionErrorNoReply);
}

// A step the controller refused because it reset (Techno's 4 to the move itself, the reply
// reporting the reset, which the bus counts before it returns) ends with the reset's code.
TEST_F(AxisProfileDone, AStepRefusedAfterAResetEndsWithTheResetsCode) {
  bus_.replies = {Reply::of(Reply::Status::ok),
                  Reply::of(Reply::Status::device_error, "axis not defined", '4')};
  bus_.on_command = [this](const std::string& c) {
    if (c.starts_with("M")) ++image_.node(0).controller_resets;
  };
  command(0, 511, ProfileCommand::move_absolute, 1, true);
  run_until([&] { return ended(0); });
  EXPECT_EQ(status(0), CommandStatus::error);
  EXPECT_EQ(input(0, ap::command_error), kActionErrorControllerReset);
}

// A reset before the command was accepted is none of its business: the refusal keeps its code.
TEST_F(AxisProfileDone, AStepRefusedAfterAnEarlierResetKeepsItsCode) {
  ++image_.node(0).controller_resets;
  bus_.replies = {Reply::of(Reply::Status::ok),
                  Reply::of(Reply::Status::device_error, "axis not defined", '4')};
  command(0, 511, ProfileCommand::move_absolute, 1, true);
  run_until([&] { return ended(0); });
  EXPECT_EQ(status(0), CommandStatus::error);
  EXPECT_EQ(input(0, ap::command_error), '4');
}

TEST_F(AxisProfileDone, APageWhoseStatusWasNeverReadAnswersTargetFailed) {
  const auto moving =
      static_cast<std::size_t>(model().find_point("in_motion") - model().points.data());
  image_.node(0).points[moving].valid = false;
  const auto r =
      server_->read(axis(0), modbus::RegisterTable::input_registers, 0, 12, WordOrder::high_first);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.exception(), modbus::ExceptionCode::gateway_target_failed);
}

}  // namespace
}  // namespace fieldgate
