#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "drivers/protocol_family.hpp"
#include "gateway/process_image.hpp"

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
};

// When each poll is due. Pure: time comes in as arguments, so it is tested without sleeping.
// Items of one node and period are spread evenly over the period (phase-staggered), and a node's
// items start staggered against other nodes too, so no tick carries all polls.
class PollPlan {
 public:
  void add(PollItem item);
  // Spreads first due times from start; call once after adding all items.
  void start(SteadyTime start);

  struct Due {
    std::size_t item;
    SteadyTime when;
  };
  // The earliest-due item among nodes for which eligible(node) holds.
  std::optional<Due> next(const std::function<bool(int node)>& eligible) const;
  // Item finished at `now`: due again one period after its last due time; when the bus fell
  // more than a period behind, missed ticks are skipped, not run back to back.
  void completed(std::size_t item, SteadyTime now);
  // A node coming back online: its polls start again from now, staggered.
  void restart_node(int node, SteadyTime now);

  PollItem& item(std::size_t i) { return items_[i]; }
  const std::vector<PollItem>& items() const { return items_; }
  // The first item of a node, used to probe an offline node.
  std::optional<std::size_t> probe_item(int node) const;

 private:
  void stagger(const std::function<bool(const PollItem&)>& select, SteadyTime start);
  std::vector<PollItem> items_;
};

}  // namespace fieldgate
