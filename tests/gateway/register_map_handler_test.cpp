// RegisterMapHandler over a bus that records each command: a Modbus write is checked whole before
// any part of it runs, and each control result is answered with its one exception.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

#include "control_table_test.hpp"
#include "gateway/register_map/register_map_handler.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
namespace asio = boost::asio;
using modbus::ExceptionCode;

class RegisterMapHandlerTest : public test::ControlTableTest {
 protected:
  void start(const std::string& modbus_section = "") {
    start_control(modbus_section);
    if (HasFatalFailure()) return;
    handler_ = std::make_unique<RegisterMapHandler>(config_, 0, image_, *actions_, *control_);
  }

  const RegisterEntry& holding(const std::string& name) const {
    for (const auto& e :
         config_->register_map.unit(1)->tables[static_cast<std::size_t>(Table::holding_registers)])
      if (e.name == name) return e;
    ADD_FAILURE() << "no holding register " << name;
    static const RegisterEntry none;
    return none;
  }
  uint16_t action_code(const std::string& name) const { return model().find_action(name)->code; }
  // The exception, or nullopt for success.
  std::optional<ExceptionCode> write(uint16_t address, std::vector<uint16_t> values) {
    const auto result =
        finish(handler_->write_registers(1, address, std::span<const uint16_t>(values)));
    if (result.ok()) return std::nullopt;
    return result.exception();
  }
  int64_t setpoint(const std::string& name) const {
    const Model& m = model();
    return image_.node(0)
        .setpoints[static_cast<std::size_t>(m.find_setpoint(name) - m.setpoints.data())];
  }

  std::unique_ptr<RegisterMapHandler> handler_;
};

TEST_F(RegisterMapHandlerTest, AWriteIsCheckedWholeBeforeAnyPartOfItRuns) {
  start();
  const auto& x = holding("target_x");
  const auto& y = holding("target_y");
  ASSERT_EQ(y.address, x.address + 2) << "target_x and target_y are neighbours";
  // target_x within its site limits, target_y within its model's; then target_x below the site's
  // minimum: the whole write is refused and target_y keeps its value.
  EXPECT_EQ(write(x.address, {0, 10, 0, 20}), std::nullopt);
  EXPECT_EQ(setpoint("target_x"), 10);
  EXPECT_EQ(setpoint("target_y"), 20);
  EXPECT_EQ(write(x.address, {0xffff, 0xffff, 0, 30}), ExceptionCode::illegal_data_value);
  EXPECT_EQ(setpoint("target_x"), 10);
  EXPECT_EQ(setpoint("target_y"), 20);
  // Half of a 32-bit value.
  EXPECT_EQ(write(x.address + 1, {5}), ExceptionCode::illegal_data_value);
  EXPECT_TRUE(bus_.sent.empty());
}

TEST_F(RegisterMapHandlerTest, MonitorOnlyTakesSetpointsAndRefusesPointsAndActions) {
  start("modbus:\n  writes_enabled: false\n");
  EXPECT_EQ(write(holding("target_x").address, {0, 7}), std::nullopt);
  EXPECT_EQ(write(holding("plane").address, {1}), ExceptionCode::illegal_function);
  EXPECT_EQ(write(holding("action.command").address, {action_code("zero")}),
            ExceptionCode::illegal_function);
  // An unknown action code is a bad value, before the policy.
  EXPECT_EQ(write(holding("action.command").address, {999}), ExceptionCode::illegal_data_value);
  EXPECT_TRUE(bus_.sent.empty());
}

TEST_F(RegisterMapHandlerTest, AHeldLineAnswersBusyOnlyOnceEveryRegisterPassedItsChecks) {
  start();
  image_.node(0).action.holding_line = true;
  EXPECT_EQ(write(holding("plane").address, {1}), ExceptionCode::server_busy);
  EXPECT_EQ(write(holding("plane").address, {3}), ExceptionCode::illegal_data_value);
  EXPECT_EQ(write(holding("action.command").address, {action_code("zero")}),
            ExceptionCode::server_busy);
  EXPECT_TRUE(bus_.sent.empty());
}

TEST_F(RegisterMapHandlerTest, TheDevicesAnswerBecomesItsException) {
  start();
  bus_.replies = {Reply::of(Reply::Status::device_error, "error 2", 2),
                  Reply::of(Reply::Status::timeout, "no reply, outcome unknown"),
                  Reply::of(Reply::Status::unreachable, "node is offline")};
  EXPECT_EQ(write(holding("plane").address, {1}), ExceptionCode::server_device_failure);
  EXPECT_EQ(write(holding("plane").address, {1}), ExceptionCode::gateway_target_failed);
  EXPECT_EQ(write(holding("plane").address, {1}), ExceptionCode::gateway_target_failed);
  EXPECT_EQ(write(holding("plane").address, {2}), std::nullopt);
  EXPECT_EQ(bus_.sent.size(), 4u);
}

}  // namespace
}  // namespace fieldgate
