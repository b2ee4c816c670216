#pragma once

// A gtest fixture for end-to-end tests: a Plant (simulators and the real daemon) and a Modbus
// TCP client to the daemon; on failure the daemon's and every simulator's log.

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "harness.hpp"

namespace fieldgate::test {

// Base is ::testing::Test or a ::testing::TestWithParam<T>; PlantType is Plant or a family's
// plant derived from it.
template <class Base = ::testing::Test, class PlantType = Plant>
class PlantFixture : public Base {
 protected:
  void start(std::unique_ptr<PlantType> plant) {
    plant_ = std::move(plant);
    client_ = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
  }
  void start(std::vector<SimulatedBus> buses, std::string modbus_extra = "") {
    start(std::make_unique<PlantType>(std::move(buses), std::move(modbus_extra)));
  }

  // Waits until ready(unit) holds for each unit in turn; fails naming the first unit that never
  // gets there, with the daemon's log.
  void wait_online(const std::vector<int>& units, const std::function<bool(int)>& ready,
                   std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    for (int unit : units)
      ASSERT_TRUE(wait_until([&] { return ready(unit); }, timeout))
          << "unit " << unit << " never came online\n"
          << plant_->daemon().log();
  }
  // wait_online until count input registers from address read without an exception.
  void wait_inputs(const std::vector<int>& units, int address, int count,
                   std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    wait_online(
        units, [&](int unit) { return client_->read_input(unit, address, count).ok(); }, timeout);
  }

  void TearDown() override {
    if (!plant_) return;
    // Every poll sent ahead (drivers/README.md, "Sending ahead") was what its family's exchange
    // then sent: pipelined_request() agrees with transact_node() in every test of every family.
    if (!this->HasFailure()) {
      EXPECT_EQ(plant_->daemon().log().find("was sent ahead, but the exchange"), std::string::npos)
          << plant_->daemon().log();
    }
    if (!this->HasFailure()) return;
    std::cerr << "--- daemon log ---\n" << plant_->daemon().log();
    for (std::size_t i = 0; i < plant_->sim_count(); ++i)
      std::cerr << "--- simulator " << i << " log ---\n" << plant_->sim(i).log();
  }

  // One register, -1 when the read fails.
  int input(int unit, int address) {
    auto r = client_->read_input(unit, address, 1);
    return r.ok() ? r.values[0] : -1;
  }
  int holding(int unit, int address) {
    auto r = client_->read_holding(unit, address, 1);
    return r.ok() ? r.values[0] : -1;
  }
  // Two registers, high word first; 0xffffffff (input_u32) or nullopt when the read fails.
  uint32_t input_u32(int unit, int address) {
    auto r = client_->read_input(unit, address, 2);
    return r.ok() ? (static_cast<uint32_t>(r.values[0]) << 16) | r.values[1] : 0xffffffff;
  }
  std::optional<int32_t> holding_i32(int unit, int address) {
    auto r = client_->read_holding(unit, address, 2);
    if (!r.ok()) return std::nullopt;
    return static_cast<int32_t>((static_cast<uint32_t>(r.values[0]) << 16) | r.values[1]);
  }

  std::unique_ptr<PlantType> plant_;
  std::unique_ptr<ModbusClient> client_;
};

using PlantTest = PlantFixture<>;

}  // namespace fieldgate::test
