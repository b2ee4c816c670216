#pragma once

#include <chrono>
#include <cstddef>
#include <optional>

#include "gateway/image/process_image.hpp"

namespace fieldgate {

// What a stream bus does next, decided from what it knows at `now` and nothing else: a pure
// function, tested with literal times (tests/gateway/bus_turn_test.cpp).
struct BusTurnInput {
  SteadyTime now{};
  bool commands_queued = false;
  // The poll the plan offers (the earliest due of an online node, rate-monotonic) and its period.
  struct Poll {
    std::size_t item = 0;
    SteadyTime when{};
    std::chrono::microseconds period{0};
  };
  std::optional<Poll> poll;
  // The probe of the offline node due first.
  std::optional<Poll> probe;
  int commands_in_row = 0;  // commands since the last poll
  int polls_in_row = 0;     // polls since the last command
  bool all_nodes_offline = false;
  SteadyTime link_opened{};
  std::chrono::microseconds probe_interval{0};
};

struct BusTurn {
  enum class Kind {
    command,      // the next queued command
    poll,         // `item`
    reopen_link,  // nothing answers: reopen, so the family's link-open procedure runs again
    sleep,        // until `until` (or a command arrives)
  };
  Kind kind = Kind::sleep;
  std::size_t item = 0;
  SteadyTime until = SteadyTime::max();
};

// Commands go first, but back-to-back commands leave every other transaction to a due poll, and
// a poll running late (by a tenth of its period) gets up to kPollsPerCommand transactions per
// command: clients flooding one unit cannot slow the polling of the others, and commands still
// get through when polls overload the line.
inline constexpr int kCommandsPerPoll = 1;
inline constexpr int kPollsPerCommand = 3;

BusTurn next_bus_turn(const BusTurnInput& in);

}  // namespace fieldgate
