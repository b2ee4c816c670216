#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "drivers/protocol_family.hpp"
#include "gateway/image/process_image.hpp"

namespace fieldgate {

// One polled request of one node and the points its reply feeds.
struct PollItem {
  int node = 0;
  Request request;
  struct Target {
    int point = 0;
    int field = 0;
  };
  std::vector<Target> targets;
  std::chrono::microseconds period{0};
  SteadyTime next_due{};
  uint64_t overruns = 0;  // periods skipped because the bus was busy
  // The item's slot: due at slot + k * period; set by start(), kept by restart_node().
  SteadyTime slot{};
  std::optional<SteadyTime> last_run;
};

// When each poll is due. Pure: time comes in as arguments, so it is tested without sleeping.
// Items of one node and period are spread evenly over the period (phase-staggered), and a node's
// items start staggered against other nodes too, so no tick carries all polls.
class PollPlan {
 public:
  void add(PollItem item);
  // Spreads first due times from start; call once after adding all items.
  void start(SteadyTime start);
  // Instead of start(), for the plan a reload made of `previous` (its nodes renumbered by
  // `moved_to`, old number -> new, -1 for a node not carried over): an item the previous plan had
  // (same node, request and period) keeps its schedule, its last run and its overruns; the
  // others are spread from `start` as start() spreads them.
  void start_after(const PollPlan& previous, const std::vector<int>& moved_to, SteadyTime start);

  struct Due {
    std::size_t item;
    SteadyTime when;
  };
  // The earliest-due item among nodes for which eligible(node) holds.
  std::optional<Due> next(const std::function<bool(int node)>& eligible) const;
  // What a bus should poll at `now`. Among items already due the shortest period goes first
  // (rate-monotonic), earliest due within a period, so under overload the fast class keeps its
  // rate and slower classes take what is left; every kStarvationGuard-th pick of a due item
  // goes to the longest-waiting one instead, so no class stops entirely. With nothing due: the
  // earliest item, to sleep until.
  std::optional<Due> pick(SteadyTime now, const std::function<bool(int node)>& eligible) const;
  static constexpr unsigned kStarvationGuard = 8;
  // Item finished at `now`: due again one period after its last due time; when the bus fell
  // more than a period behind, missed ticks are skipped, not run back to back.
  void completed(std::size_t item, SteadyTime now);
  // A node coming (back) online: each of its items is due at its original slot's next tick,
  // or at once when it has not run for a whole period (or never), so however often the node
  // goes offline and online, every item runs at least once per period while it is online.
  void restart_node(int node, SteadyTime now);

  PollItem& item(std::size_t i) { return items_[i]; }
  const std::vector<PollItem>& items() const { return items_; }
  // The first item of a node, used to probe an offline node.
  std::optional<std::size_t> probe_item(int node) const;

 private:
  void stagger(const std::function<bool(const PollItem&)>& select, SteadyTime start);
  std::vector<PollItem> items_;
  unsigned picks_ = 0;  // completed polls
  SteadyTime start_{};
};

}  // namespace fieldgate
