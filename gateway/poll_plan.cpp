#include "gateway/poll_plan.hpp"

#include <map>

namespace fieldgate {

void PollPlan::add(PollItem item) {
  items_.push_back(std::move(item));
}

void PollPlan::stagger(const std::function<bool(const PollItem&)>& select, SteadyTime start) {
  // Group by period; within a period spread every selected item evenly.
  std::map<std::chrono::microseconds::rep, std::vector<std::size_t>> by_period;
  for (std::size_t i = 0; i < items_.size(); ++i)
    if (select(items_[i])) by_period[items_[i].period.count()].push_back(i);
  for (auto& [period, indices] : by_period) {
    const auto n = static_cast<std::chrono::microseconds::rep>(indices.size());
    for (std::size_t k = 0; k < indices.size(); ++k)
      items_[indices[k]].next_due =
          start +
          std::chrono::microseconds(period * static_cast<std::chrono::microseconds::rep>(k) / n);
  }
}

void PollPlan::start(SteadyTime start) {
  stagger([](const PollItem&) { return true; }, start);
}

std::optional<PollPlan::Due> PollPlan::next(const std::function<bool(int)>& eligible) const {
  std::optional<Due> best;
  for (std::size_t i = 0; i < items_.size(); ++i) {
    const auto& it = items_[i];
    if (!eligible(it.node)) continue;
    if (!best || it.next_due < best->when) best = Due{i, it.next_due};
  }
  return best;
}

void PollPlan::completed(std::size_t index, SteadyTime now) {
  auto& it = items_[index];
  it.next_due += it.period;
  if (it.next_due <= now) {
    const auto behind = now - it.next_due;
    const auto skipped = behind / it.period + 1;
    it.overruns += static_cast<uint64_t>(skipped);
    it.next_due += it.period * skipped;
  }
}

void PollPlan::restart_node(int node, SteadyTime now) {
  stagger([node](const PollItem& it) { return it.node == node; }, now);
}

std::optional<std::size_t> PollPlan::probe_item(int node) const {
  for (std::size_t i = 0; i < items_.size(); ++i)
    if (items_[i].node == node) return i;
  return std::nullopt;
}

}  // namespace fieldgate
