#pragma once

// The fixture of the control path's tests (control_service_test, register_map_handler_test): one
// Techno C142 "table" (unit 1, target_x limited to 0..50000 by the site) on a bus that records
// each command and answers as told (ScriptedBus); its configuration, process image, action
// runner and control service.

#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

#include <chrono>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "config_file_test.hpp"
#include "gateway/bus/node_image_setup.hpp"
#include "gateway/control/control_service.hpp"
#include "scripted_bus.hpp"

namespace fieldgate::test {

class ControlTableTest : public ConfigFileTest {
 protected:
  // Loads the configuration (modbus_section ahead of the bus) and builds the control path.
  void start_control(const std::string& modbus_section = "") {
    std::optional<LoadedConfig> loaded;
    ASSERT_EQ(
        load(modbus_section + "buses:\n  - name: b\n    protocol: techno-c\n"
                              "    serial: {device: /dev/null, baud: 9600}\n    nodes:\n"
                              "      - {name: table, address: 0, model: techno-c142, unit_id: 1,\n"
                              "         limits: {target_x: {min: 0, max: 50000}}}\n",
             &loaded),
        "");
    config_ = std::make_shared<const LoadedConfig>(std::move(*loaded));
    image_ = ProcessImage({make_node_image(config_->gateway.buses[0].nodes[0])});
    const auto bus_of = [this](int) -> Bus& { return bus_; };
    actions_ = std::make_unique<ActionRunner>(io_.get_executor(), image_, bus_of);
    control_ = std::make_unique<ControlService>(config_, image_, *actions_, bus_of);
  }
  void TearDown() override {
    if (actions_) actions_->stop();
    ConfigFileTest::TearDown();
  }

  const Model& model() const { return *config_->gateway.buses[0].nodes[0].model; }

  // Runs `operation` on the io_context for 200 ms, by when it must have finished; its result.
  template <class Operation>
  auto finish(Operation operation) {
    using namespace std::chrono_literals;
    auto future = boost::asio::co_spawn(io_, std::move(operation), boost::asio::use_future);
    io_.run_for(200ms);
    io_.restart();
    EXPECT_EQ(future.wait_for(0s), std::future_status::ready);
    return future.get();
  }

  boost::asio::io_context io_;
  ScriptedBus bus_;
  std::shared_ptr<const LoadedConfig> config_;
  ProcessImage image_;
  std::unique_ptr<ActionRunner> actions_;
  std::unique_ptr<ControlService> control_;
};

}  // namespace fieldgate::test
