// The control service over a bus that records each command and answers as told: the rules every
// front door's writes meet (range, model and site limits, policy, a held line), what reaches the
// device, and each way a reply ends a write.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

#include "control_table_test.hpp"
#include "gateway/control/control_service.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
namespace asio = boost::asio;

class ControlServiceTest : public test::ControlTableTest {
 protected:
  void SetUp() override {
    ConfigFileTest::SetUp();
    start_control();
  }

  int setpoint(const std::string& name) const {
    return static_cast<int>(model().find_setpoint(name) - model().setpoints.data());
  }
  int point(const std::string& name) const {
    return static_cast<int>(model().find_point(name) - model().points.data());
  }
  ControlWrite setpoint_write(const std::string& name, int64_t value) const {
    return {ControlWrite::Kind::setpoint, 0, setpoint(name), value};
  }
  ControlWrite point_write(const std::string& name, int64_t value) const {
    return {ControlWrite::Kind::point, 0, point(name), value};
  }
  ControlWrite action(const std::string& name) const {
    return {ControlWrite::Kind::action, 0, 0, model().find_action(name)->code};
  }
  ControlResult write(ControlWrite w, WritePolicy policy = {}) {
    return finish(control_->write(w, policy));
  }
};

TEST_F(ControlServiceTest, ASetpointWithinItsLimitsIsStoredAndNothingIsSent) {
  EXPECT_TRUE(write(setpoint_write("target_x", 1234)).ok());
  EXPECT_EQ(image_.node(0).setpoints[static_cast<std::size_t>(setpoint("target_x"))], 1234);
  EXPECT_TRUE(bus_.sent.empty());
}

TEST_F(ControlServiceTest, TheSiteLimitNarrowsTheModelsAndNamesTheBoundInItsDetail) {
  // The model allows -8000000; the site's limits: 0.
  const auto below = write(setpoint_write("target_x", -1));
  EXPECT_EQ(below.status, ControlStatus::out_of_range);
  EXPECT_NE(below.detail.find("minimum 0"), std::string::npos) << below.detail;
  const auto above = write(setpoint_write("target_x", 50001));
  EXPECT_EQ(above.status, ControlStatus::out_of_range);
  EXPECT_NE(above.detail.find("maximum 50000"), std::string::npos) << above.detail;
  // The model's own bound where the site sets none.
  EXPECT_EQ(write(setpoint_write("speed_x", 29)).status, ControlStatus::out_of_range);
  // The type's range first: a uint16 setpoint cannot hold 70000, whatever its limits.
  EXPECT_EQ(write(setpoint_write("speed_x", 70000)).status, ControlStatus::out_of_range);
  EXPECT_EQ(image_.node(0).setpoints[static_cast<std::size_t>(setpoint("target_x"))], 0);
}

TEST_F(ControlServiceTest, APointWriteIsSentAndReadsBackOnceTheControllerConfirmsIt) {
  EXPECT_TRUE(write(point_write("plane", 2)).ok());
  ASSERT_EQ(bus_.sent.size(), 1u);
  EXPECT_EQ(bus_.sent[0], "e2");
  const auto& value = image_.node(0).points[static_cast<std::size_t>(point("plane"))];
  EXPECT_TRUE(value.valid);
  EXPECT_EQ(value.value, 2);
  EXPECT_EQ(write(point_write("plane", 3)).status, ControlStatus::out_of_range);
  EXPECT_EQ(bus_.sent.size(), 1u) << "nothing out of range is sent";
}

TEST_F(ControlServiceTest, EachWayAReplyEndsAWriteHasItsOwnResult) {
  bus_.replies = {Reply::of(Reply::Status::device_error, "error 3", 3),
                  Reply::of(Reply::Status::timeout, "no reply, outcome unknown"),
                  Reply::of(Reply::Status::garbled, "'x'"),
                  Reply::of(Reply::Status::unreachable, "node is offline"),
                  Reply::of(Reply::Status::link_down, "write failed")};
  const auto refused = write(point_write("plane", 1));
  EXPECT_EQ(refused.status, ControlStatus::device_error);
  EXPECT_EQ(refused.device_code, 3);
  EXPECT_EQ(refused.detail, "error 3");
  EXPECT_EQ(write(point_write("plane", 1)).status, ControlStatus::outcome_unknown);
  EXPECT_EQ(write(point_write("plane", 1)).status, ControlStatus::outcome_unknown);
  EXPECT_EQ(write(point_write("plane", 1)).status, ControlStatus::unreachable);
  EXPECT_EQ(write(point_write("plane", 1)).status, ControlStatus::outcome_unknown)
      << "a link that failed while writing may have delivered the write";
  // None of them confirmed the value: it does not read back.
  EXPECT_FALSE(image_.node(0).points[static_cast<std::size_t>(point("plane"))].valid);
}

TEST_F(ControlServiceTest, AMonitorOnlyDoorKeepsSetpointsAndRefusesEverythingThatReachesTheDevice) {
  const WritePolicy monitor_only{true, false};
  EXPECT_TRUE(write(setpoint_write("target_x", 10), monitor_only).ok());
  EXPECT_EQ(write(point_write("plane", 1), monitor_only).status, ControlStatus::writes_disabled);
  EXPECT_EQ(write(action("zero"), monitor_only).status, ControlStatus::writes_disabled);
  const WritePolicy read_only{false, false};
  EXPECT_EQ(write(setpoint_write("target_x", 11), read_only).status,
            ControlStatus::writes_disabled);
  EXPECT_TRUE(bus_.sent.empty());
  // A value out of range is named as such, whatever the policy.
  EXPECT_EQ(write(setpoint_write("target_x", -5), read_only).status, ControlStatus::out_of_range);
}

TEST_F(ControlServiceTest, AnUnknownActionCodeIsOutOfRangeAndAnUnknownPointHasNoTarget) {
  EXPECT_EQ(write({ControlWrite::Kind::action, 0, 0, 999}).status, ControlStatus::out_of_range);
  EXPECT_EQ(write({ControlWrite::Kind::point, 0, point("position_x"), 1}).status,
            ControlStatus::no_such_target)
      << "a read-only point";
  EXPECT_EQ(write({ControlWrite::Kind::setpoint, 0, 10000, 1}).status,
            ControlStatus::no_such_target);
  EXPECT_EQ(write({ControlWrite::Kind::setpoint, 7, 0, 1}).status, ControlStatus::no_such_target);
}

TEST_F(ControlServiceTest, AHeldLineRefusesPointWritesAndActionsButLetsAStopThrough) {
  image_.node(0).action.holding_line = true;
  EXPECT_EQ(write(point_write("plane", 1)).status, ControlStatus::line_held);
  EXPECT_EQ(write(action("zero")).status, ControlStatus::line_held);
  EXPECT_TRUE(write(setpoint_write("target_x", 5)).ok()) << "a setpoint stays in the gateway";
  EXPECT_TRUE(bus_.sent.empty());
  const ActionDef& stop = *model().find_action("stop");
  EXPECT_FALSE(control_->line_held_for(0, stop));
  EXPECT_TRUE(control_->check(action("stop"), {}).ok());
}

TEST_F(ControlServiceTest, AnActionsStepsGoOutWithItsSetpointsAndItsRefusalIsTheDevicesCode) {
  ASSERT_TRUE(write(setpoint_write("target_x", 400)).ok());
  const auto started = write(action("move_absolute"));
  // z0, then the move with the stored target.
  ASSERT_EQ(bus_.sent.size(), 2u);
  EXPECT_EQ(bus_.sent[1].rfind("M400,", 0), 0u) << bus_.sent[1];
  EXPECT_TRUE(started.ok() || started.status == ControlStatus::outcome_unknown)
      << to_string(started.status) << ": " << started.detail;
  bus_.sent.clear();
  image_.node(0).action = {};
  bus_.replies = {Reply::of(Reply::Status::device_error, "refused", 7)};
  const auto refused = write(action("zero"));
  EXPECT_EQ(refused.status, ControlStatus::device_error);
  EXPECT_EQ(refused.device_code, 7);
}

TEST_F(ControlServiceTest, ACommandsValuesAreCheckedByNameAgainstTheSameLimits) {
  EXPECT_TRUE(control_->check_value(0, "target_x", 100).ok());
  EXPECT_EQ(control_->check_value(0, "target_x", -100).status, ControlStatus::out_of_range);
  EXPECT_EQ(control_->check_value(0, "plane", 3).status, ControlStatus::out_of_range);
  EXPECT_EQ(control_->check_value(0, "nonesuch", 0).status, ControlStatus::no_such_target);
}

}  // namespace
}  // namespace fieldgate
