#pragma once

#include <array>
#include <cstdint>
#include <memory>

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
};

}  // namespace fieldgate
