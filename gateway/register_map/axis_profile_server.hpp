#pragma once

#include <boost/asio/awaitable.hpp>

#include <memory>
#include <span>

#include "gateway/config/gateway_config.hpp"
#include "gateway/control/control_service.hpp"
#include "gateway/image/process_image.hpp"
#include "gateway/modbus/request_handler.hpp"
#include "gateway/register_map/action_runner.hpp"

namespace fieldgate {

// One axis of one node, as a profile unit ID presents it.
struct ProfileUnit {
  int node_index = 0;
  const NodeConfig* node = nullptr;
  ModelPtr model;
  int axis = 0;  // index into model->profile_axes
};

// Serves the axis profile page (mapping/axis_profile.hpp) of profile units: reads from the
// process image, commands through the model's actions with the sequence-number handshake.
class AxisProfileServer {
 public:
  AxisProfileServer(ProcessImage& image, ActionRunner& actions, ControlService& control,
                    const ModbusConfig& modbus);
  ~AxisProfileServer();

  modbus::ReadRegistersResult read(const ProfileUnit& unit, modbus::RegisterTable table,
                                   uint16_t address, uint16_t count, WordOrder order);
  asio::awaitable<modbus::WriteResult> write(ProfileUnit unit, uint16_t address,
                                             std::span<const uint16_t> values, WordOrder order);

 private:
  ProfileAxisRuntime& runtime(const ProfileUnit& unit);
  AxisObservation observe(const ProfileUnit& unit, const ProfileAxisRuntime& rt) const;
  asio::awaitable<modbus::WriteResult> command(ProfileUnit unit, ProfileCommand command,
                                               uint16_t sequence);
  void abort_shared_stops(const ProfileUnit& unit, ProfileCommand cmd);
  asio::awaitable<void> follow(ProfileUnit unit, uint64_t generation, uint64_t action_generation,
                               std::size_t step, std::shared_ptr<bool> alive);

  ProcessImage& image_;
  ActionRunner& actions_;
  ControlService& control_;
  const ModbusConfig& modbus_;
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);
};

}  // namespace fieldgate
