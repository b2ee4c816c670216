#pragma once

#include <boost/asio/awaitable.hpp>

#include <memory>
#include <optional>
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

// What a profile axis presents, in domain terms: its input page before it becomes registers.
// Every reader of an axis (the Modbus page, the web console) takes it from here.
struct AxisReading {
  std::optional<int64_t> position;  // nullopt: never read
  std::optional<int64_t> velocity;  // nullopt: the controller does not report it
  bool online = false;
  uint16_t status_word = 0;  // StatusBit bits
  PlcopenState state = PlcopenState::disabled;
  uint16_t error_id = 0;
  uint16_t sequence = 0;
  ProfileCommand command = ProfileCommand::none;
  CommandStatus status = CommandStatus::idle;
  uint16_t command_error = 0;
  uint16_t supported = 0;  // bit n: command code n
};

AxisObservation observe_axis(const ProfileUnit& unit, const NodeImage& node,
                             const ProfileAxisRuntime& rt);
AxisReading read_axis(const ProfileUnit& unit, const NodeImage& node, const ProfileAxisRuntime& rt);
bool axis_readings_fresh(const ProfileUnit& unit, const NodeImage& node);

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
  // The part of a command that goes to the line: its point writes and first action in the
  // node's turn, then the follow-up.
  asio::awaitable<modbus::WriteResult> run_command(ProfileUnit unit, uint64_t generation,
                                                   ActionArguments arguments,
                                                   std::vector<ControlWrite> point_writes,
                                                   const ActionDef* first,
                                                   std::shared_ptr<bool> alive);
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
