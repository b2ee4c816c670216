// The stream bus's choice of what to do next, with literal times: commands before polls, but
// never so many that polls starve; late polls get the line back; offline nodes are probed; a
// link on which nothing answers is reopened.
#include <gtest/gtest.h>

#include <optional>

#include "gateway/bus/bus_turn.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

const SteadyTime t0 = SteadyTime{} + 1000s;

BusTurnInput::Poll poll_at(std::size_t item, SteadyTime when,
                           std::chrono::microseconds period = 100ms) {
  return {item, when, period};
}

// The bus at t0, with its next poll (if any) and commands queued or not.
BusTurnInput at_t0(std::optional<BusTurnInput::Poll> poll = std::nullopt,
                   bool commands_queued = false) {
  BusTurnInput in;
  in.now = t0;
  in.poll = poll;
  in.commands_queued = commands_queued;
  return in;
}

TEST(BusTurn, NothingQueuedAndNothingDueSleepsUntilTheNextPoll) {
  BusTurnInput in = at_t0(poll_at(4, t0 + 30ms));
  const auto turn = next_bus_turn(in);
  EXPECT_EQ(turn.kind, BusTurn::Kind::sleep);
  EXPECT_EQ(turn.until, t0 + 30ms);
  in.poll.reset();
  EXPECT_EQ(next_bus_turn(in).until, SteadyTime::max()) << "no poll at all: until a command";
}

TEST(BusTurn, ADuePollRunsAndACommandGoesBeforeAPollNotYetDue) {
  BusTurnInput in = at_t0(poll_at(2, t0));
  auto turn = next_bus_turn(in);
  EXPECT_EQ(turn.kind, BusTurn::Kind::poll);
  EXPECT_EQ(turn.item, 2u);
  in.poll = poll_at(2, t0 + 1ms);
  in.commands_queued = true;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::command);
}

TEST(BusTurn, BackToBackCommandsLeaveTheNextTurnToADuePoll) {
  // The poll: due, 5 ms late: not late for a 100 ms period.
  BusTurnInput in = at_t0(poll_at(1, t0 - 5ms), /*commands_queued=*/true);
  in.commands_in_row = 0;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::command);
  in.commands_in_row = kCommandsPerPoll;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::poll);
}

TEST(BusTurn, APollRunningLateGetsSeveralTurnsPerCommand) {
  // The poll: more than a tenth of its 100 ms period late.
  BusTurnInput in = at_t0(poll_at(1, t0 - 11ms), /*commands_queued=*/true);
  for (int polls = 0; polls < kPollsPerCommand; ++polls) {
    in.polls_in_row = polls;
    EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::poll) << polls << " polls in a row";
  }
  in.polls_in_row = kPollsPerCommand;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::command);
  // Exactly a tenth late is not late yet.
  in.poll = poll_at(1, t0 - 10ms);
  in.polls_in_row = 0;
  in.commands_in_row = 0;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::command);
}

TEST(BusTurn, TheProbeOfAnOfflineNodeRunsWhenItIsDueBeforeThePoll) {
  BusTurnInput in = at_t0(poll_at(1, t0 + 50ms));
  in.probe = poll_at(7, t0 - 1ms);
  auto turn = next_bus_turn(in);
  EXPECT_EQ(turn.kind, BusTurn::Kind::poll);
  EXPECT_EQ(turn.item, 7u);
  in.probe = poll_at(7, t0 + 60ms);
  turn = next_bus_turn(in);
  EXPECT_EQ(turn.kind, BusTurn::Kind::sleep);
  EXPECT_EQ(turn.until, t0 + 50ms);
}

TEST(BusTurn, ALinkOnWhichNothingAnswersIsReopenedOnceAProbeIntervalHasPassed) {
  BusTurnInput in = at_t0();
  in.probe = poll_at(3, t0);
  in.all_nodes_offline = true;
  in.probe_interval = 500ms;
  in.link_opened = t0 - 499ms;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::poll) << "opened too recently: probe";
  in.link_opened = t0 - 500ms;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::reopen_link);
  in.all_nodes_offline = false;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::poll) << "a node answers: keep the link";
  // A due poll of an online node is never a reason to reopen.
  in.all_nodes_offline = true;
  in.probe.reset();
  in.poll = poll_at(3, t0);
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::poll);
}

}  // namespace
}  // namespace fieldgate
