#include "gateway/bus/bus_turn.hpp"

#include <algorithm>

namespace fieldgate {

BusTurn next_bus_turn(const BusTurnInput& in) {
  // The poll or the probe, whichever is due first.
  std::optional<BusTurnInput::Poll> chosen = in.poll;
  bool is_probe = false;
  if (in.probe && (!chosen || in.probe->when < chosen->when)) {
    chosen = in.probe;
    is_probe = true;
  }
  const bool poll_due = chosen && chosen->when <= in.now;
  bool command_first = in.commands_queued;
  if (command_first && poll_due) {
    const bool late = in.now - chosen->when > chosen->period / 10;
    command_first =
        late ? in.command_credit >= kPollsPerCommand : in.commands_in_row < kCommandsPerPoll;
  }
  if (command_first) return {BusTurn::Kind::command, 0, in.now};
  if (poll_due) {
    if (is_probe && in.all_nodes_offline && in.now - in.link_opened >= in.probe_interval)
      return {BusTurn::Kind::reopen_link, chosen->item, in.now};
    return {BusTurn::Kind::poll, chosen->item, in.now};
  }
  return {BusTurn::Kind::sleep, 0, chosen ? chosen->when : SteadyTime::max()};
}

int command_credit_after(int credit, BusTurn::Kind turn) {
  switch (turn) {
    case BusTurn::Kind::command:
      return std::max(0, credit - kPollsPerCommand);
    case BusTurn::Kind::poll:
    case BusTurn::Kind::reopen_link:
      return std::min(kCommandCreditMax, credit + 1);
    case BusTurn::Kind::sleep:
      break;
  }
  return credit;
}

}  // namespace fieldgate
