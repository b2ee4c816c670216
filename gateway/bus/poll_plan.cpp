#include "gateway/bus/poll_plan.hpp"

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
    for (std::size_t k = 0; k < indices.size(); ++k) {
      auto& it = items_[indices[k]];
      it.next_due = start + std::chrono::microseconds(
                                period * static_cast<std::chrono::microseconds::rep>(k) / n);
      it.slot = it.next_due;
    }
  }
}

void PollPlan::start(SteadyTime start) {
  start_ = start;
  stagger([](const PollItem&) { return true; }, start);
}

void PollPlan::start_after(const PollPlan& previous, const std::vector<int>& moved_to,
                           SteadyTime start) {
  start_ = start;
  picks_ = previous.picks_;
  std::vector<bool> kept(items_.size(), false);
  for (const auto& old : previous.items_) {
    const auto to = static_cast<std::size_t>(old.node);
    if (to >= moved_to.size() || moved_to[to] < 0) continue;
    for (std::size_t i = 0; i < items_.size(); ++i) {
      auto& it = items_[i];
      if (kept[i] || it.node != moved_to[to] || it.period != old.period ||
          it.request.command != old.request.command)
        continue;
      it.next_due = old.next_due;
      it.slot = old.slot;
      it.last_run = old.last_run;
      it.overruns = old.overruns;
      kept[i] = true;
      break;
    }
  }
  std::vector<bool> fresh(items_.size());
  for (std::size_t i = 0; i < items_.size(); ++i) fresh[i] = !kept[i];
  stagger([&](const PollItem& it) { return fresh[static_cast<std::size_t>(&it - items_.data())]; },
          start);
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

std::optional<PollPlan::Due> PollPlan::pick(SteadyTime now,
                                            const std::function<bool(int)>& eligible) const {
  std::optional<std::size_t> urgent, oldest, earliest;
  for (std::size_t i = 0; i < items_.size(); ++i) {
    const auto& it = items_[i];
    if (!eligible(it.node)) continue;
    if (!earliest || it.next_due < items_[*earliest].next_due) earliest = i;
    if (it.next_due > now) continue;
    if (!oldest || it.next_due < items_[*oldest].next_due) oldest = i;
    if (!urgent || it.period < items_[*urgent].period ||
        (it.period == items_[*urgent].period && it.next_due < items_[*urgent].next_due))
      urgent = i;
  }
  if (!urgent) {
    if (!earliest) return std::nullopt;
    return Due{*earliest, items_[*earliest].next_due};
  }
  const std::size_t chosen = ((picks_ + 1) % kStarvationGuard == 0) ? *oldest : *urgent;
  return Due{chosen, items_[chosen].next_due};
}

void PollPlan::completed(std::size_t index, SteadyTime now) {
  auto& it = items_[index];
  it.last_run = now;
  ++picks_;
  it.next_due += it.period;
  if (it.next_due <= now) {
    const auto behind = now - it.next_due;
    const auto skipped = behind / it.period + 1;
    it.overruns += static_cast<uint64_t>(skipped);
    it.next_due += it.period * skipped;
  }
}

void PollPlan::restart_node(int node, SteadyTime now) {
  for (auto& it : items_) {
    if (it.node != node || it.period.count() <= 0) continue;
    const SteadyTime since = it.last_run ? *it.last_run : start_;
    if (now - since >= it.period) {
      it.next_due = now;
      continue;
    }
    // The first tick of the item's own slot at or after now: within one period.
    auto due = it.slot;
    if (due < now)
      due += it.period * ((now - due + it.period - std::chrono::nanoseconds(1)) / it.period);
    it.next_due = std::min(due, since + it.period);
  }
}

std::optional<std::size_t> PollPlan::probe_item(int node) const {
  for (std::size_t i = 0; i < items_.size(); ++i)
    if (items_[i].node == node) return i;
  return std::nullopt;
}

}  // namespace fieldgate
