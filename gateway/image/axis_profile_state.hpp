#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>

#include "gateway/image/node_turn.hpp"
#include "mapping/axis_profile.hpp"

namespace fieldgate {

struct ActionState;

// What the gateway keeps per profile axis between requests: the PLC's setpoints, the handshake
// and the ErrorStop latch. Lives in the node's image, so it outlasts a reload of an unchanged bus.
struct ProfileAxisRuntime {
  bool initialised = false;            // setpoints taken from the model's defaults at first use
  std::array<int64_t, 4> setpoints{};  // target, velocity, acceleration, deceleration
  uint16_t sequence = 0;
  ProfileCommand command = ProfileCommand::none;
  CommandStatus status = CommandStatus::idle;
  uint16_t command_error = 0;
  uint64_t generation = 0;  // a newer command supersedes the follow-up of an older one
  // The axis's own action status: the node's action register is one per node, and a command to
  // one axis must not supersede the other axis's (created at first use).
  std::shared_ptr<ActionState> action;
  bool error_latched = false;
  uint16_t error_id = 0;
  // What the running command runs with and what proves it done: its arguments (for each of its
  // actions), the position it must end at (moves), and the controller's resets when it was
  // accepted (a reset since ends it failed).
  ActionArguments arguments;
  std::optional<int64_t> target;
  uint64_t resets = 0;
  std::optional<int64_t> reset_count;
  std::chrono::steady_clock::time_point accepted{};
};

}  // namespace fieldgate
