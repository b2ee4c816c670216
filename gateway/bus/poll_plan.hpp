#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <utility>
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
  std::chrono::microseconds period{0};  // fixed once added to a plan
  uint64_t overruns = 0;                // periods skipped because the bus was busy
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
  // What a bus should poll at `now`, among nodes eligible to be polled (set_eligible; every
  // node is until it is said otherwise). Among items already due the shortest period goes first
  // (rate-monotonic), earliest due within a period, so under overload the fast class keeps its
  // rate and slower classes take what is left; every kStarvationGuard-th pick of a due item
  // goes to the longest-waiting one instead, so no class stops entirely. With nothing due: the
  // earliest item, to sleep until. Costs a look at each period's earliest item, not a scan.
  std::optional<Due> pick(SteadyTime now);
  // What pick(now) would give once `item` had completed at `now`, leaving the plan as it is: the
  // poll a bus may send ahead while `item` is on the wire.
  std::optional<Due> pick_after(std::size_t item, SteadyTime now);
  // Whether a node's items take part in pick() (a stream bus polls no offline node).
  void set_eligible(int node, bool eligible);
  static constexpr unsigned kStarvationGuard = 8;
  // Item finished at `now`: due again one period after its last due time; when the bus fell
  // more than a period behind, missed ticks are skipped, not run back to back.
  void completed(std::size_t item, SteadyTime now);
  // A node coming (back) online: each of its items is due at its original slot's next tick,
  // or at once when it has not run for a whole period (or never), so however often the node
  // goes offline and online, every item runs at least once per period while it is online.
  void restart_node(int node, SteadyTime now);
  // A node coming back on a bus that does not restart its slots (CAN): each overdue item moves
  // to the latest due time of its own phase not after now, so every one runs at once, in its
  // order, without the offline time counted as overruns.
  void resume_node(int node, SteadyTime now);

  PollItem& item(std::size_t i) { return items_[i]; }
  const std::vector<PollItem>& items() const { return items_; }
  SteadyTime next_due(std::size_t i) const { return schedule_[i].next_due; }
  // The first item of a node, used to probe an offline node.
  std::optional<std::size_t> probe_item(int node) const;

 private:
  void stagger(const std::function<bool(std::size_t item)>& select, SteadyTime start);
  // Whether eligible(node) holds, asked once per node and scan (verdicts_ caches it).
  bool eligible_once(int node, const std::function<bool(int node)>& eligible) const;
  std::vector<PollItem> items_;
  // What a scan reads, apart from the items (which carry requests and targets) and packed, so
  // that picking among thousands of items on a bus stays within the cache.
  struct Schedule {
    SteadyTime next_due{};
    std::chrono::microseconds period{0};
    int node = 0;
  };
  std::vector<Schedule> schedule_;                       // parallel to items_
  std::vector<std::vector<std::size_t>> items_of_node_;  // in the order added
  const std::vector<std::size_t>& items_of(int node) const;
  mutable std::vector<signed char> verdicts_;  // per node: -1 not asked yet, 0, 1
  // pick()'s index: per period (shortest first) the eligible items by (next due, item), kept up
  // to date item by item and rebuilt only after items are added or the plan is (re)started.
  void rebuild_queues();
  void requeue(std::size_t item, SteadyTime old_due);
  using QueueEntry = std::pair<SteadyTime, std::size_t>;
  std::vector<std::set<QueueEntry>> queues_;  // one per period, shortest first
  std::vector<std::size_t> queue_of_;         // per item
  std::vector<bool> eligible_;                // per node
  bool queues_stale_ = true;
  unsigned picks_ = 0;  // completed polls
  SteadyTime start_{};
};

}  // namespace fieldgate
