#pragma once

#include <functional>
#include <memory>

#include "gateway/config/config_loader.hpp"
#include "gateway/control/control_service.hpp"
#include "gateway/image/process_image.hpp"
#include "gateway/modbus/request_handler.hpp"
#include "gateway/register_map/action_runner.hpp"
#include "gateway/register_map/axis_profile_server.hpp"

namespace fieldgate {

// Serves one listener's register map (its unit-ID space and access options): reads from the
// process image, writes through the control service. Every listener has its own handler over
// the one process image.
class RegisterMapHandler final : public modbus::RequestHandler {
 public:
  RegisterMapHandler(std::shared_ptr<const LoadedConfig> config, std::size_t listener,
                     ProcessImage& image, ActionRunner& actions, ControlService& control);

  modbus::ReadBitsResult read_bits(uint8_t unit, modbus::BitTable table, uint16_t address,
                                   uint16_t count) override;
  modbus::ReadRegistersResult read_registers(uint8_t unit, modbus::RegisterTable table,
                                             uint16_t address, uint16_t count) override;
  asio::awaitable<modbus::WriteResult> write_registers(uint8_t unit, uint16_t address,
                                                       std::span<const uint16_t> values) override;
  asio::awaitable<modbus::WriteResult> write_coils(uint8_t unit, uint16_t address,
                                                   std::vector<bool> values) override;
  modbus::DeviceIdentificationResult device_identification(uint8_t unit) override;

 private:
  struct EntryValue;
  // The node a unit ID names on this listener: the one place a unit ID is resolved.
  const UnitMap* unit_of(uint8_t unit_id) const { return map_.unit(unit_id); }
  // A point's value is served only while fresh (point_is_fresh at `now`), or, for an offline
  // or faulted node, as `offline_reads` says.
  std::optional<modbus::ExceptionCode> entry_value(const UnitMap& unit, const RegisterEntry& e,
                                                   SteadyTime now, int64_t& value) const;

  std::shared_ptr<const LoadedConfig> config_;
  const RegisterMap& map_;
  const ModbusConfig& modbus_;
  ProcessImage& image_;
  ControlService& control_;
  // The axis a profile unit ID stands for, or nullptr (a native unit, or none).
  const ProfileUnit* profile_unit(uint8_t unit) const;

  std::vector<const NodeConfig*> nodes_;  // by the gateway's node number
  std::map<uint8_t, ProfileUnit> profile_units_;
  AxisProfileServer profile_;
};

}  // namespace fieldgate
