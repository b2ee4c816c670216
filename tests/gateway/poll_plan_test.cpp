#include <gtest/gtest.h>

#include <initializer_list>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "gateway/bus/poll_plan.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

PollItem item(int node, const char* command, std::chrono::microseconds period) {
  PollItem it;
  it.node = node;
  it.request.command = command;
  it.period = period;
  return it;
}

const auto all = [](int) { return true; };

// A plan of the items, in this order.
PollPlan plan_of(std::initializer_list<PollItem> items) {
  PollPlan plan;
  for (const auto& i : items) plan.add(i);
  return plan;
}

TEST(PollPlan, ItemsOfAPeriodAreSpreadEvenly) {
  PollPlan plan;
  for (int node = 0; node < 2; ++node) {
    plan.add(item(node, "a", 100ms));
    plan.add(item(node, "b", 100ms));
  }
  const SteadyTime t0{};
  plan.start(t0);
  std::set<SteadyTime::duration::rep> offsets;
  for (std::size_t i = 0; i < plan.items().size(); ++i)
    offsets.insert((plan.next_due(i) - t0) / 1ms);
  EXPECT_EQ(offsets, (std::set<SteadyTime::duration::rep>{0, 25, 50, 75}));
}

// A reload that changed one node's period and added a node ahead of the others: every other
// item keeps its schedule; the changed and the new items are spread from the reload's time.
TEST(PollPlan, AReloadsPlanKeepsTheScheduleOfEveryItemItDidNotChange) {
  PollPlan before = plan_of({item(0, "a", 100ms), item(0, "b", 1s), item(1, "a", 100ms)});
  const SteadyTime t0{};
  before.start(t0);
  before.completed(0, t0 + 3ms);
  before.completed(2, t0 + 53ms);

  PollPlan after = plan_of({
      item(0, "a", 100ms),  // the new node, ahead of the others
      item(1, "a", 100ms),  // node 0 before the reload, unchanged
      item(1, "b", 500ms),  // its period changed
      item(2, "a", 100ms),  // node 1 before the reload, unchanged
  });
  const SteadyTime reload = t0 + 60ms;
  after.start_after(before, {1, 2}, reload);

  EXPECT_EQ(after.next_due(1), before.next_due(0));
  EXPECT_EQ(after.items()[1].last_run, before.items()[0].last_run);
  EXPECT_EQ(after.next_due(3), before.next_due(2));
  EXPECT_EQ(after.items()[3].slot, before.items()[2].slot);
  EXPECT_EQ(after.next_due(0), reload) << "the new node's first item, at once";
  EXPECT_EQ(after.next_due(2), reload) << "alone in its period: at once";
  EXPECT_FALSE(after.items()[2].last_run);
}

TEST(PollPlan, NextPicksEarliestEligible) {
  PollPlan plan = plan_of({item(0, "a", 100ms), item(1, "b", 100ms)});
  const SteadyTime t0{};
  plan.start(t0);
  auto due = plan.next(all);
  ASSERT_TRUE(due);
  EXPECT_EQ(plan.item(due->item).node, 0);
  due = plan.next([](int node) { return node != 0; });
  ASSERT_TRUE(due);
  EXPECT_EQ(plan.item(due->item).node, 1);
  EXPECT_EQ(due->when, t0 + 50ms);
  EXPECT_FALSE(plan.next([](int) { return false; }));
}

TEST(PollPlan, CompletedKeepsTheRhythm) {
  PollPlan plan = plan_of({item(0, "a", 100ms)});
  const SteadyTime t0{};
  plan.start(t0);
  plan.completed(0, t0 + 3ms);  // ran a little late
  EXPECT_EQ(plan.next_due(0), t0 + 100ms);
  EXPECT_EQ(plan.item(0).overruns, 0u);
}

TEST(PollPlan, FallingBehindSkipsMissedTicks) {
  PollPlan plan = plan_of({item(0, "a", 100ms)});
  const SteadyTime t0{};
  plan.start(t0);
  plan.completed(0, t0 + 350ms);  // the bus was busy for three periods
  EXPECT_EQ(plan.next_due(0), t0 + 400ms);
  EXPECT_EQ(plan.item(0).overruns, 3u);
}

// Runs a bus on the plan from time 0 for `run`, each poll taking `transaction`; the polls made,
// by command.
std::map<std::string, int> polls_over(PollPlan& plan, std::chrono::microseconds run,
                                      std::chrono::microseconds transaction) {
  std::map<std::string, int> polls;
  const SteadyTime end = SteadyTime{} + run;
  SteadyTime now{};
  plan.start(now);
  while (now < end) {
    auto due = plan.pick(now);
    if (!due) {
      ADD_FAILURE() << "nothing to poll";
      break;
    }
    if (due->when >= end) break;
    if (due->when > now) now = due->when;
    now += transaction;
    ++polls[plan.item(due->item).request.command];
    plan.completed(due->item, now);
  }
  return polls;
}

TEST(PollPlan, SlowAndFastClassesInterleaveOverTime) {
  PollPlan plan = plan_of({item(0, "fast", 100ms), item(0, "slow", 1000ms)});
  auto polls = polls_over(plan, 2000ms, 5ms);
  EXPECT_EQ(polls["fast"], 20);
  EXPECT_EQ(polls["slow"], 2);
}

TEST(PollPlan, RestartNodeReschedulesFromNow) {
  PollPlan plan = plan_of({item(0, "a", 100ms), item(0, "b", 100ms), item(1, "c", 100ms)});
  const SteadyTime t0{};
  plan.start(t0);
  plan.restart_node(0, t0 + 10s);
  EXPECT_GE(plan.next_due(0), t0 + 10s);
  EXPECT_GE(plan.next_due(1), t0 + 10s);
  EXPECT_LT(plan.next_due(2), t0 + 10s);
  EXPECT_EQ(plan.probe_item(1), 2u);
  EXPECT_FALSE(plan.probe_item(5));
}

TEST(PollPlan, RestartKeepsTheOriginalSlot) {
  PollPlan plan = plan_of({
      item(0, "a", 100ms), item(0, "b", 100ms),  // slot t0 + 50 ms
  });
  const SteadyTime t0{};
  plan.start(t0);
  plan.completed(0, t0 + 1ms);
  plan.completed(1, t0 + 51ms);
  // Offline for a moment, back before either item missed a period: their own ticks.
  plan.restart_node(0, t0 + 70ms);
  EXPECT_EQ(plan.next_due(0), t0 + 100ms);
  EXPECT_EQ(plan.next_due(1), t0 + 150ms);
  // Back after a longer absence: both missed a period and are due at once.
  plan.restart_node(0, t0 + 400ms);
  EXPECT_EQ(plan.next_due(0), t0 + 400ms);
  EXPECT_EQ(plan.next_due(1), t0 + 400ms);
}

// A node that goes offline and online every 500 ms (a heartbeat that flaps): its 5 s class
// must still run at least once every 5 s of online time.
TEST(PollPlan, EveryClassRunsWithinItsPeriodWhileANodeFlaps) {
  PollPlan plan = plan_of(
      {item(0, "fast", 100ms), item(0, "slow1", 5s), item(0, "slow2", 5s), item(0, "slow3", 5s)});
  SteadyTime now{};
  plan.start(now);
  bool online = true;
  std::map<std::string, std::vector<SteadyTime>> runs;
  SteadyTime flip = now + 500ms;
  while (now < SteadyTime{} + 30s) {
    if (now >= flip) {
      online = !online;
      plan.set_eligible(0, online);
      if (online) plan.restart_node(0, now);
      flip += online ? 450ms : 50ms;  // mostly online
    }
    auto due = plan.pick(now);
    if (!due || due->when > now) {
      now += 1ms;
      continue;
    }
    now += 2ms;
    runs[plan.item(due->item).request.command].push_back(now);
    plan.completed(due->item, now);
  }
  for (const char* name : {"slow1", "slow2", "slow3"}) {
    const auto& r = runs[name];
    ASSERT_GE(r.size(), 5u) << name;
    for (std::size_t i = 1; i < r.size(); ++i)
      EXPECT_LE(r[i] - r[i - 1], 5s + 100ms) << name << " run " << i;
  }
}

// Polls need far more than the line can carry: the fast class keeps its rate (it fits on its
// own), slower classes share what is left, and none stops entirely.
TEST(PollPlan, UnderOverloadTheFastClassKeepsItsPriority) {
  PollPlan plan;
  for (int node = 0; node < 4; ++node) {
    plan.add(item(node, "fast", 100ms));
    for (int k = 0; k < 10; ++k) plan.add(item(node, "slow", 200ms));
  }
  // Each poll takes 10 ms: fast alone needs 40 %, everything 240 %.
  auto polls = polls_over(plan, 10s, 10ms);
  EXPECT_GE(polls["fast"], 4 * 100 * 95 / 100);  // 4 nodes x 10/s x 10 s, within 5 %
  EXPECT_GT(polls["slow"], 0);
  EXPECT_LT(polls["slow"], 40 * 50);  // the slow class cannot have its full rate
}

// pick() answers from an index kept across completions, restarts and eligibility changes; here it
// is held against the rule itself, a scan of every item, through a long random run.
TEST(PollPlan, PickAgreesWithAScanOfEveryItemThroughARandomRun) {
  PollPlan plan;
  const int nodes = 12;
  const std::chrono::microseconds periods[] = {10ms, 10ms, 50ms, 200ms, 1s};
  std::mt19937 random(7);
  for (int node = 0; node < nodes; ++node)
    for (int k = 0; k < 1 + node % 4; ++k)
      plan.add(item(node, "r", periods[static_cast<std::size_t>(node + k) % 5]));
  SteadyTime now{};
  plan.start(now);
  std::vector<bool> eligible(nodes, true);
  unsigned completed = 0;
  const auto scan = [&]() -> std::optional<PollPlan::Due> {
    std::optional<std::size_t> urgent, oldest, earliest;
    for (std::size_t i = 0; i < plan.items().size(); ++i) {
      const auto& it = plan.item(i);
      if (!eligible[static_cast<std::size_t>(it.node)]) continue;
      const auto due = plan.next_due(i);
      if (!earliest || due < plan.next_due(*earliest)) earliest = i;
      if (due > now) continue;
      if (!oldest || due < plan.next_due(*oldest)) oldest = i;
      if (!urgent || it.period < plan.item(*urgent).period ||
          (it.period == plan.item(*urgent).period && due < plan.next_due(*urgent)))
        urgent = i;
    }
    if (!urgent) {
      if (!earliest) return std::nullopt;
      return PollPlan::Due{*earliest, plan.next_due(*earliest)};
    }
    const auto chosen = ((completed + 1) % PollPlan::kStarvationGuard == 0) ? *oldest : *urgent;
    return PollPlan::Due{chosen, plan.next_due(chosen)};
  };
  for (int step = 0; step < 20000; ++step) {
    const auto expected = scan();
    const auto got = plan.pick(now);
    ASSERT_EQ(got.has_value(), expected.has_value()) << "step " << step;
    if (got) {
      ASSERT_EQ(got->item, expected->item) << "step " << step;
      ASSERT_EQ(got->when, expected->when) << "step " << step;
    }
    const auto roll = random() % 100;
    if (roll < 3) {  // a node goes offline or comes back
      const int node = static_cast<int>(random() % nodes);
      eligible[static_cast<std::size_t>(node)] = !eligible[static_cast<std::size_t>(node)];
      plan.set_eligible(node, eligible[static_cast<std::size_t>(node)]);
      if (eligible[static_cast<std::size_t>(node)]) plan.restart_node(node, now);
    } else if (got && got->when <= now) {
      now += std::chrono::microseconds(500 + random() % 4000);  // the transaction
      plan.completed(got->item, now);
      ++completed;
    } else {
      now = got ? got->when : now + 10ms;
    }
  }
}

}  // namespace
}  // namespace fieldgate

namespace fieldgate {
namespace {

// pick_after(i, t) is what completed(i, t) then pick(t) give, and changes nothing: a plan asked
// at every turn runs exactly as a plan never asked.
TEST(PollPlan, PickAfterForeseesTheNextPickAndLeavesThePlanAsItWas) {
  std::mt19937 random(7);
  PollPlan asked, untouched;
  const std::chrono::microseconds periods[] = {1ms, 10ms, 25ms, 100ms};
  for (int node = 0; node < 6; ++node)
    for (int k = 0; k < 3; ++k) {
      const auto it = item(node, k == 0 ? "a" : k == 1 ? "b" : "c", periods[random() % 4]);
      asked.add(it);
      untouched.add(it);
    }
  const SteadyTime start{};
  asked.start(start);
  untouched.start(start);
  SteadyTime now = start;
  int foreseen = 0;
  for (int turn = 0; turn < 3000; ++turn) {
    now += std::chrono::microseconds(random() % 2500);
    if (turn % 97 == 0) {
      const int node = static_cast<int>(random() % 6);
      const bool eligible = random() % 2 == 0;
      asked.set_eligible(node, eligible);
      untouched.set_eligible(node, eligible);
    }
    const auto due = asked.pick(now);
    const auto due_untouched = untouched.pick(now);
    ASSERT_EQ(due.has_value(), due_untouched.has_value()) << "turn " << turn;
    if (!due || due->when > now) continue;
    ASSERT_EQ(due->item, due_untouched->item) << "turn " << turn;
    const auto finished = now + std::chrono::microseconds(random() % 3000);
    const auto foreseen_pick = asked.pick_after(due->item, finished);
    PollPlan copy = asked;
    copy.completed(due->item, finished);
    const auto actual = copy.pick(finished);
    ASSERT_EQ(foreseen_pick.has_value(), actual.has_value()) << "turn " << turn;
    if (actual) {
      EXPECT_EQ(foreseen_pick->item, actual->item) << "turn " << turn;
      EXPECT_EQ(foreseen_pick->when, actual->when) << "turn " << turn;
      ++foreseen;
    }
    for (std::size_t i = 0; i < asked.items().size(); ++i)
      ASSERT_EQ(asked.next_due(i), untouched.next_due(i)) << "item " << i << ", turn " << turn;
    asked.completed(due->item, finished);
    untouched.completed(due->item, finished);
    now = finished;
  }
  EXPECT_GT(foreseen, 1000);
  for (std::size_t i = 0; i < asked.items().size(); ++i) {
    EXPECT_EQ(asked.items()[i].overruns, untouched.items()[i].overruns);
    EXPECT_EQ(asked.items()[i].last_run, untouched.items()[i].last_run);
  }
}

}  // namespace
}  // namespace fieldgate
