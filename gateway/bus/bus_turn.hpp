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
  // Polls earned toward commands that go ahead of late polls (see kPollsPerCommand).
  int command_credit = 0;
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

// Commands go first, but back-to-back commands leave every other transaction to a due poll. When
// polls run late (by a tenth of their period, as on a saturated line) a command goes ahead of them
// only on credit: each poll earns one, a command spends kPollsPerCommand, and the credit holds at
// most kCommandBurst commands' worth. An occasional command (a PLC's move) waits for no more than
// the transaction on the wire; clients flooding the line get one command per kPollsPerCommand
// polls, so they cannot slow the polling of the others, and commands still get through.
inline constexpr int kCommandsPerPoll = 1;
inline constexpr int kPollsPerCommand = 3;
inline constexpr int kCommandBurst = 3;
inline constexpr int kCommandCreditMax = kPollsPerCommand * kCommandBurst;

BusTurn next_bus_turn(const BusTurnInput& in);

// The credit after a turn of the given kind.
int command_credit_after(int credit, BusTurn::Kind turn);

}  // namespace fieldgate
