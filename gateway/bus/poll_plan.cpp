#include "gateway/bus/poll_plan.hpp"

#include <algorithm>
#include <map>

namespace fieldgate {

void PollPlan::add(PollItem item) {
  const auto node = static_cast<std::size_t>(item.node);
  if (items_of_node_.size() <= node) {
    verdicts_.resize(node + 1, -1);
    eligible_.resize(node + 1, true);
    items_of_node_.resize(node + 1);
  }
  items_of_node_[node].push_back(items_.size());
  queues_stale_ = true;
  schedule_.push_back({SteadyTime{}, item.period, item.node});
  items_.push_back(std::move(item));
}

void PollPlan::stagger(const std::function<bool(std::size_t)>& select, SteadyTime start) {
  // Group by period; within a period spread every selected item evenly.
  std::map<std::chrono::microseconds::rep, std::vector<std::size_t>> by_period;
  for (std::size_t i = 0; i < items_.size(); ++i)
    if (select(i)) by_period[schedule_[i].period.count()].push_back(i);
  for (auto& [period, indices] : by_period) {
    const auto n = static_cast<std::chrono::microseconds::rep>(indices.size());
    for (std::size_t k = 0; k < indices.size(); ++k) {
      auto& due = schedule_[indices[k]].next_due;
      due = start +
            std::chrono::microseconds(period * static_cast<std::chrono::microseconds::rep>(k) / n);
      items_[indices[k]].slot = due;
    }
  }
}

void PollPlan::start(SteadyTime start) {
  start_ = start;
  stagger([](std::size_t) { return true; }, start);
  queues_stale_ = true;
}

void PollPlan::set_eligible(int node, bool eligible) {
  const auto n = static_cast<std::size_t>(node);
  if (n >= eligible_.size() || eligible_[n] == eligible) return;
  eligible_[n] = eligible;
  if (queues_stale_) return;
  for (const std::size_t i : items_of_node_[n]) {
    auto& queue = queues_[queue_of_[i]];
    if (eligible)
      queue.insert({schedule_[i].next_due, i});
    else
      queue.erase({schedule_[i].next_due, i});
  }
}

void PollPlan::rebuild_queues() {
  std::map<std::chrono::microseconds::rep, std::size_t> by_period;
  for (const auto& s : schedule_) by_period.emplace(s.period.count(), 0);
  queues_.clear();
  for (auto& entry : by_period) {
    entry.second = queues_.size();
    queues_.emplace_back();
  }
  queue_of_.resize(schedule_.size());
  for (std::size_t i = 0; i < schedule_.size(); ++i) {
    const auto& s = schedule_[i];
    queue_of_[i] = by_period[s.period.count()];
    if (eligible_[static_cast<std::size_t>(s.node)]) queues_[queue_of_[i]].insert({s.next_due, i});
  }
  queues_stale_ = false;
}

void PollPlan::requeue(std::size_t item, SteadyTime old_due) {
  if (queues_stale_ || !eligible_[static_cast<std::size_t>(schedule_[item].node)]) return;
  auto& queue = queues_[queue_of_[item]];
  queue.erase({old_due, item});
  queue.insert({schedule_[item].next_due, item});
}

void PollPlan::start_after(const PollPlan& previous, const std::vector<int>& moved_to,
                           SteadyTime start) {
  start_ = start;
  picks_ = previous.picks_;
  std::vector<bool> kept(items_.size(), false);
  for (std::size_t o = 0; o < previous.items_.size(); ++o) {
    const auto& old = previous.items_[o];
    const auto to = static_cast<std::size_t>(old.node);
    if (to >= moved_to.size() || moved_to[to] < 0) continue;
    for (std::size_t i = 0; i < items_.size(); ++i) {
      auto& it = items_[i];
      if (kept[i] || it.node != moved_to[to] || it.period != old.period ||
          it.request.command != old.request.command)
        continue;
      schedule_[i].next_due = previous.schedule_[o].next_due;
      it.slot = old.slot;
      it.last_run = old.last_run;
      it.overruns = old.overruns;
      kept[i] = true;
      break;
    }
  }
  std::vector<bool> fresh(items_.size());
  for (std::size_t i = 0; i < items_.size(); ++i) fresh[i] = !kept[i];
  stagger([&](std::size_t i) { return fresh[i]; }, start);
  queues_stale_ = true;
}

bool PollPlan::eligible_once(int node, const std::function<bool(int)>& eligible) const {
  auto& verdict = verdicts_[static_cast<std::size_t>(node)];
  if (verdict < 0) verdict = eligible(node) ? 1 : 0;
  return verdict == 1;
}

std::optional<PollPlan::Due> PollPlan::next(const std::function<bool(int)>& eligible) const {
  std::fill(verdicts_.begin(), verdicts_.end(), -1);
  std::optional<Due> best;
  for (std::size_t i = 0; i < schedule_.size(); ++i) {
    const auto& it = schedule_[i];
    if (best && it.next_due >= best->when) continue;
    if (eligible_once(it.node, eligible)) best = Due{i, it.next_due};
  }
  return best;
}

std::optional<PollPlan::Due> PollPlan::pick(SteadyTime now) {
  if (queues_stale_) rebuild_queues();
  // Each queue's front is its period's earliest item; ties go to the lower item number.
  const QueueEntry* urgent = nullptr;
  const QueueEntry* oldest = nullptr;
  const QueueEntry* earliest = nullptr;
  for (const auto& queue : queues_) {
    if (queue.empty()) continue;
    const QueueEntry& front = *queue.begin();
    if (!earliest || front < *earliest) earliest = &front;
    if (front.first > now) continue;
    if (!urgent) urgent = &front;  // queues run from the shortest period
    if (!oldest || front < *oldest) oldest = &front;
  }
  if (!urgent) {
    if (!earliest) return std::nullopt;
    return Due{earliest->second, earliest->first};
  }
  const QueueEntry& chosen = ((picks_ + 1) % kStarvationGuard == 0) ? *oldest : *urgent;
  return Due{chosen.second, chosen.first};
}

std::optional<PollPlan::Due> PollPlan::pick_after(std::size_t index, SteadyTime now) {
  auto& it = items_[index];
  auto& due = schedule_[index].next_due;
  const SteadyTime was_due = due;
  const auto last_run = it.last_run;
  const auto overruns = it.overruns;
  const auto picks = picks_;
  completed(index, now);
  const auto next = pick(now);
  const SteadyTime moved_to = due;
  due = was_due;
  it.last_run = last_run;
  it.overruns = overruns;
  picks_ = picks;
  requeue(index, moved_to);
  return next;
}

void PollPlan::completed(std::size_t index, SteadyTime now) {
  auto& it = items_[index];
  auto& due = schedule_[index].next_due;
  const SteadyTime was_due = due;
  it.last_run = now;
  ++picks_;
  due += it.period;
  if (due <= now) {
    const auto behind = now - due;
    const auto skipped = behind / it.period + 1;
    it.overruns += static_cast<uint64_t>(skipped);
    due += it.period * skipped;
  }
  requeue(index, was_due);
}

const std::vector<std::size_t>& PollPlan::items_of(int node) const {
  static const std::vector<std::size_t> none;
  const auto n = static_cast<std::size_t>(node);
  return node >= 0 && n < items_of_node_.size() ? items_of_node_[n] : none;
}

void PollPlan::restart_node(int node, SteadyTime now) {
  for (const std::size_t i : items_of(node)) {
    const auto& it = items_[i];
    auto& next_due = schedule_[i].next_due;
    if (it.period.count() <= 0) continue;
    const SteadyTime was_due = next_due;
    const SteadyTime since = it.last_run ? *it.last_run : start_;
    if (now - since >= it.period) {
      next_due = now;
    } else {
      // The first tick of the item's own slot at or after now: within one period.
      auto due = it.slot;
      if (due < now)
        due += it.period * ((now - due + it.period - std::chrono::nanoseconds(1)) / it.period);
      next_due = std::min(due, since + it.period);
    }
    requeue(i, was_due);
  }
}

void PollPlan::resume_node(int node, SteadyTime now) {
  for (const std::size_t i : items_of(node)) {
    auto& s = schedule_[i];
    if (s.next_due >= now || s.period.count() <= 0) continue;
    const SteadyTime was_due = s.next_due;
    s.next_due += s.period * ((now - s.next_due) / s.period);
    requeue(i, was_due);
  }
}

std::optional<std::size_t> PollPlan::probe_item(int node) const {
  const auto& items = items_of(node);
  if (items.empty()) return std::nullopt;
  return items.front();
}

}  // namespace fieldgate
