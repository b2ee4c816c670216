#include "sim/copley/variables.hpp"

#include <algorithm>

namespace fieldgate::sim::copley {
namespace {

constexpr bool R = true;
constexpr bool F = true;
constexpr bool no = false;

// Defaults are the values of a commissioned amplifier's flash, chosen to be plausible and to
// make the manual's transcripts come out (0x6b holds the §4.2.4 example). The flash copy of
// 0x24 is 0 so a simulated amplifier powers up disabled; see README.md.
std::vector<VariableInfo> build_catalog() {
  using A = Access;
  std::vector<VariableInfo> c = {
      {0x00, "current loop proportional gain Cp", R, F, A::read_write, {150}},
      {0x01, "current loop integral gain Ci", R, F, A::read_write, {30}},
      {0x02, "programmed current (0.01 A)", R, F, A::read_write, {0}},
      {0x0c, "actual current (0.01 A)", R, no, A::monitor, {}},
      {0x15, "commanded current (0.01 A)", R, no, A::monitor, {}},
      {0x17, "load position (counts)", R, no, A::monitor, {}},
      {0x18, "actual motor velocity (0.1 counts/s)", R, no, A::monitor, {}},
      {0x19, "analog input scaling factor", R, F, A::read_write, {10000}},
      {0x1a, "analog input offset (mV)", R, F, A::read_write, {0}},
      {0x1b, "sin input voltage (mV)", R, no, A::monitor, {}},
      {0x1c, "cos input voltage (mV)", R, no, A::monitor, {}},
      {0x1d, "analog input voltage (mV)", R, no, A::monitor, {}},
      {0x1e, "bus voltage (100 mV)", R, no, A::monitor, {}},
      {0x20, "amplifier temperature (deg C)", R, no, A::monitor, {}},
      {0x21, "peak current limit (0.01 A)", R, F, A::read_write, {1000}},
      {0x22, "continuous current limit (0.01 A)", R, F, A::read_write, {500}},
      {0x23, "I2T time limit (ms)", R, F, A::read_write, {1000}},
      {0x24, "amplifier desired state", R, F, A::read_write, {0}},
      {0x25, "limited current (0.01 A)", R, no, A::monitor, {}},
      {0x26, "analog input dead band (mV)", R, F, A::read_write, {0}},
      {0x27, "velocity loop proportional gain Vp", R, F, A::read_write, {1000}},
      {0x28, "velocity loop integral gain Vi", R, F, A::read_write, {100}},
      {0x29, "limited velocity (0.1 counts/s)", R, no, A::monitor, {}},
      {0x2a, "velocity loop error (0.1 counts/s)", R, no, A::monitor, {}},
      {0x2c, "commanded velocity (0.1 counts/s)", R, no, A::monitor, {}},
      {0x2d, "limited position (counts)", R, no, A::monitor, {}},
      {0x2f, "programmed velocity command (0.1 counts/s)", R, F, A::read_write, {0}},
      {0x30, "position loop proportional gain Pp", R, F, A::read_write, {1000}},
      {0x32, "actual motor position (counts)", R, no, A::monitor, {}},
      {0x33, "velocity feed-forward Vff", R, F, A::read_write, {16384}},
      {0x34, "acceleration feed-forward Aff", R, F, A::read_write, {0}},
      {0x35, "following error (counts)", R, no, A::monitor, {}},
      {0x36, "velocity loop acceleration limit (1000 counts/s2)", R, F, A::read_write, {100}},
      {0x37, "velocity loop deceleration limit (1000 counts/s2)", R, F, A::read_write, {100}},
      {0x39, "fast stop ramp (1000 counts/s2)", R, F, A::read_write, {200}},
      {0x3a, "velocity loop velocity limit (0.01 counts/s)", R, F, A::read_write, {100000000}},
      {0x3b, "profile velocity (0.1 counts/s)", R, no, A::monitor, {}},
      {0x3c, "profile acceleration (10 counts/s2)", R, no, A::monitor, {}},
      {0x3d, "commanded position (counts)", R, no, A::monitor, {}},
      {0x5e, "actual load velocity (0.1 counts/s)", R, no, A::monitor, {}},
      // The value count of 0x5f is not given; it takes the same nine words as 0x6b.
      {0x5f,
       "velocity loop output filter coefficients",
       R,
       F,
       A::read_write,
       {0, 0, 0, 0, 0, 0, 0, 0, 0}},
      {0x6a, "current ramp rate (mA/s)", R, F, A::read_write, {0}},
      {0x6b,
       "velocity loop command filter coefficients",
       R,
       F,
       A::read_write,
       {-7936, 200, 0, 775, 1550, 775, -12774, 32763, 5813}},
      {0x70, "output 1 configuration", R, F, A::read_write, {0, 0}},
      {0x71, "output 2 configuration", R, F, A::read_write, {0, 0}},
      {0x72, "output 3 configuration", R, F, A::read_write, {0, 0}},
      {0x73, "output 4 configuration", R, F, A::read_write, {0, 0}},
      {0x74, "output 5 configuration", R, F, A::read_write, {0, 0}},
      {0x75, "output 6 configuration", R, F, A::read_write, {0, 0}},
      {0x76, "output 7 configuration", R, F, A::read_write, {0, 0}},
      {0x77, "output 8 configuration", R, F, A::read_write, {0, 0}},
      {0x90, "serial baud rate", R, no, A::read_write, {9600}},
      {0xa0, "event status register", R, no, A::read_only, {}},
      {0xa4, "fault register (latched, write 1 to clear)", R, no, A::read_write, {0}},
      {0xa6, "digital input states", R, no, A::read_only, {}},
      {0xa8, "digital input command configuration", R, F, A::read_write, {0}},
      {0xa9, "digital input scaling", R, F, A::read_write, {0x00010001}},
      {0xab, "digital output states", R, no, A::read_write, {0}},
      {0xae, "current loop offset (0.01 A)", R, F, A::read_write, {0}},
      {0xb0, "phase angle (deg)", R, no, A::monitor, {}},
      {0xb8, "positive software limit (counts)", R, F, A::read_write, {0}},
      {0xb9, "negative software limit (counts)", R, F, A::read_write, {0}},
      {0xbf, "homing current delay time (ms)", R, F, A::read_write, {250}},
      {0xc2, "homing method", R, F, A::read_write, {544}},
      {0xc3, "homing fast velocity (0.1 counts/s)", R, F, A::read_write, {20000}},
      {0xc4, "homing slow velocity (0.1 counts/s)", R, F, A::read_write, {4000}},
      {0xc5, "homing acceleration (10 counts/s2)", R, F, A::read_write, {10000}},
      {0xc6, "home offset (counts)", R, F, A::read_write, {0}},
      {0xc7, "homing current limit (0.01 A)", R, F, A::read_write, {100}},
      {0xc8, "trajectory profile type", R, F, A::read_write, {0}},
      {0xc9, "trajectory status register", R, no, A::read_only, {}},
      {0xca, "position command (counts)", R, F, A::read_write, {0}},
      {0xcb, "trajectory maximum velocity (0.1 counts/s)", R, F, A::read_write, {10000}},
      {0xcc, "trajectory maximum acceleration (10 counts/s2)", R, F, A::read_write, {10000}},
      {0xcd, "trajectory maximum deceleration (10 counts/s2)", R, F, A::read_write, {10000}},
      {0xce, "trajectory maximum jerk (100 counts/s3)", R, F, A::read_write, {1000}},
      {0xcf, "abort deceleration rate (10 counts/s2)", R, F, A::read_write, {20000}},
      {0xe3, "position loop gain multiplier (100 = x1)", R, F, A::read_write, {100}},
  };
  std::sort(c.begin(), c.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return c;
}

const std::vector<VariableInfo>& catalog() {
  static const std::vector<VariableInfo> instance = build_catalog();
  return instance;
}

}  // namespace

const VariableInfo* find_variable(int id) {
  const auto& c = catalog();
  const auto it =
      std::lower_bound(c.begin(), c.end(), id, [](const auto& v, int key) { return v.id < key; });
  return it != c.end() && it->id == id ? &*it : nullptr;
}

std::span<const VariableInfo> variable_catalog() {
  return catalog();
}

}  // namespace fieldgate::sim::copley
