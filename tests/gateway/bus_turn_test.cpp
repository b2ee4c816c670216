// The stream bus's choice of what to do next, with literal times: commands before polls, but
// never so many that polls starve; late polls get the line back; offline nodes are probed; a
// link on which nothing answers is reopened.
#include <gtest/gtest.h>

#include <optional>
#include <string>

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

TEST(BusTurn, ACommandGoesAheadOfALatePollOnlyOnCredit) {
  // The poll: more than a tenth of its 100 ms period late.
  BusTurnInput in = at_t0(poll_at(1, t0 - 11ms), /*commands_queued=*/true);
  in.command_credit = kPollsPerCommand - 1;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::poll);
  in.command_credit = kPollsPerCommand;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::command);
  // Exactly a tenth late is not late yet: the command goes first without credit.
  in.poll = poll_at(1, t0 - 10ms);
  in.command_credit = 0;
  in.commands_in_row = 0;
  EXPECT_EQ(next_bus_turn(in).kind, BusTurn::Kind::command);
}

TEST(BusTurn, OnASaturatedLineABurstOfCommandsGoesFirstThenOnePerPollsPerCommand) {
  // Polls always late, commands always queued (a client flooding the line), credit full as after
  // a quiet stretch.
  BusTurnInput in = at_t0(poll_at(1, t0 - 50ms), /*commands_queued=*/true);
  int credit = kCommandCreditMax;
  std::string turns;
  for (int i = 0; i < kCommandBurst + 3 * (kPollsPerCommand + 1); ++i) {
    in.command_credit = credit;
    const auto kind = next_bus_turn(in).kind;
    in.commands_in_row = kind == BusTurn::Kind::command ? in.commands_in_row + 1 : 0;
    credit = command_credit_after(credit, kind);
    turns += kind == BusTurn::Kind::command ? 'C' : kind == BusTurn::Kind::poll ? 'P' : '?';
  }
  EXPECT_EQ(turns, std::string(kCommandBurst, 'C') + "PPPCPPPCPPPC");
}

TEST(BusTurn, TheCreditIsEarnedByPollsSpentByCommandsAndBounded) {
  EXPECT_EQ(command_credit_after(0, BusTurn::Kind::poll), 1);
  EXPECT_EQ(command_credit_after(kCommandCreditMax, BusTurn::Kind::poll), kCommandCreditMax);
  EXPECT_EQ(command_credit_after(kPollsPerCommand + 1, BusTurn::Kind::command), 1);
  EXPECT_EQ(command_credit_after(1, BusTurn::Kind::command), 0) << "never below nothing";
  EXPECT_EQ(command_credit_after(2, BusTurn::Kind::sleep), 2);
  EXPECT_EQ(command_credit_after(2, BusTurn::Kind::reopen_link), 3) << "a reopen is a poll's turn";
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
