#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

namespace fieldgate::sim::copley {

enum class Access {
  read_write,
  read_only,  // status registers (0xa0, 0xa6, 0xc9)
  monitor,    // run-time values computed from the drive state
};

// One variable of the digest's §4 catalog (every ID the manual names).
struct VariableInfo {
  int id;
  std::string_view name;
  bool in_ram;
  bool in_flash;
  Access access;
  std::vector<std::int32_t> defaults;  // power-up (flash) values; size = value count

  std::size_t value_count() const { return defaults.empty() ? 1 : defaults.size(); }
};

const VariableInfo* find_variable(int id);
std::span<const VariableInfo> variable_catalog();

// Variable IDs the simulator gives behaviour to.
namespace var {
inline constexpr int programmed_current = 0x02;
inline constexpr int actual_current = 0x0c;
inline constexpr int commanded_current = 0x15;
inline constexpr int load_position = 0x17;
inline constexpr int actual_velocity = 0x18;
inline constexpr int sin_voltage = 0x1b;
inline constexpr int cos_voltage = 0x1c;
inline constexpr int analog_voltage = 0x1d;
inline constexpr int bus_voltage = 0x1e;
inline constexpr int temperature = 0x20;
inline constexpr int peak_current = 0x21;
inline constexpr int desired_state = 0x24;
inline constexpr int limited_current = 0x25;
inline constexpr int limited_velocity = 0x29;
inline constexpr int velocity_error = 0x2a;
inline constexpr int commanded_velocity = 0x2c;
inline constexpr int limited_position = 0x2d;
inline constexpr int programmed_velocity = 0x2f;
inline constexpr int motor_position = 0x32;
inline constexpr int following_error = 0x35;
inline constexpr int velocity_accel = 0x36;
inline constexpr int velocity_decel = 0x37;
inline constexpr int velocity_limit = 0x3a;
inline constexpr int profile_velocity = 0x3b;
inline constexpr int profile_acceleration = 0x3c;
inline constexpr int commanded_position = 0x3d;
inline constexpr int load_velocity = 0x5e;
inline constexpr int current_ramp = 0x6a;
inline constexpr int output_config_first = 0x70;
inline constexpr int output_config_last = 0x77;
inline constexpr int baud_rate = 0x90;
inline constexpr int event_status = 0xa0;
inline constexpr int fault_register = 0xa4;
inline constexpr int digital_inputs = 0xa6;
inline constexpr int digital_outputs = 0xab;
inline constexpr int phase_angle = 0xb0;
inline constexpr int positive_limit = 0xb8;
inline constexpr int negative_limit = 0xb9;
inline constexpr int homing_method = 0xc2;
inline constexpr int homing_fast_velocity = 0xc3;
inline constexpr int homing_slow_velocity = 0xc4;
inline constexpr int homing_acceleration = 0xc5;
inline constexpr int home_offset = 0xc6;
inline constexpr int profile_type = 0xc8;
inline constexpr int trajectory_status = 0xc9;
inline constexpr int position_command = 0xca;
inline constexpr int max_velocity = 0xcb;
inline constexpr int max_acceleration = 0xcc;
inline constexpr int max_deceleration = 0xcd;
inline constexpr int max_jerk = 0xce;
inline constexpr int abort_deceleration = 0xcf;
}  // namespace var

}  // namespace fieldgate::sim::copley
