#include <gtest/gtest.h>

#include <set>

#include "gateway/poll_plan.hpp"

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

TEST(PollPlan, ItemsOfAPeriodAreSpreadEvenly) {
  PollPlan plan;
  for (int node = 0; node < 2; ++node) {
    plan.add(item(node, "a", 100ms));
    plan.add(item(node, "b", 100ms));
  }
  const SteadyTime t0{};
  plan.start(t0);
  std::set<SteadyTime::duration::rep> offsets;
  for (const auto& it : plan.items()) offsets.insert((it.next_due - t0) / 1ms);
  EXPECT_EQ(offsets, (std::set<SteadyTime::duration::rep>{0, 25, 50, 75}));
}

TEST(PollPlan, NextPicksEarliestEligible) {
  PollPlan plan;
  plan.add(item(0, "a", 100ms));
  plan.add(item(1, "b", 100ms));
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
  PollPlan plan;
  plan.add(item(0, "a", 100ms));
  const SteadyTime t0{};
  plan.start(t0);
  plan.completed(0, t0 + 3ms);  // ran a little late
  EXPECT_EQ(plan.item(0).next_due, t0 + 100ms);
  EXPECT_EQ(plan.item(0).overruns, 0u);
}

TEST(PollPlan, FallingBehindSkipsMissedTicks) {
  PollPlan plan;
  plan.add(item(0, "a", 100ms));
  const SteadyTime t0{};
  plan.start(t0);
  plan.completed(0, t0 + 350ms);  // the bus was busy for three periods
  EXPECT_EQ(plan.item(0).next_due, t0 + 400ms);
  EXPECT_EQ(plan.item(0).overruns, 3u);
}

TEST(PollPlan, SlowAndFastClassesInterleaveOverTime) {
  PollPlan plan;
  plan.add(item(0, "fast", 100ms));
  plan.add(item(0, "slow", 1000ms));
  SteadyTime now{};
  plan.start(now);
  int fast = 0, slow = 0;
  // Simulate 2 s of a bus whose transactions take 5 ms.
  while (now < SteadyTime{} + 2000ms) {
    auto due = plan.next(all);
    ASSERT_TRUE(due);
    if (due->when >= SteadyTime{} + 2000ms) break;
    if (due->when > now) now = due->when;
    now += 5ms;
    (plan.item(due->item).request.command == "fast" ? fast : slow)++;
    plan.completed(due->item, now);
  }
  EXPECT_EQ(fast, 20);
  EXPECT_EQ(slow, 2);
}

TEST(PollPlan, RestartNodeReschedulesFromNow) {
  PollPlan plan;
  plan.add(item(0, "a", 100ms));
  plan.add(item(0, "b", 100ms));
  plan.add(item(1, "c", 100ms));
  const SteadyTime t0{};
  plan.start(t0);
  plan.restart_node(0, t0 + 10s);
  EXPECT_GE(plan.item(0).next_due, t0 + 10s);
  EXPECT_GE(plan.item(1).next_due, t0 + 10s);
  EXPECT_LT(plan.item(2).next_due, t0 + 10s);
  EXPECT_EQ(plan.probe_item(1), 2u);
  EXPECT_FALSE(plan.probe_item(5));
}

}  // namespace
}  // namespace fieldgate
