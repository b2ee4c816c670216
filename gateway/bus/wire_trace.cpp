#include "gateway/bus/wire_trace.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <optional>

#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

namespace {

std::vector<WireTrace*>& registry() {
  static std::vector<WireTrace*> traces;
  return traces;
}

WireTrace::Sink& sink() {
  static WireTrace::Sink s;
  return s;
}

WireTrace::Observer& observer() {
  static WireTrace::Observer o;
  return o;
}

}  // namespace

TokenBucket::TokenBucket(double rate, double burst) : rate_(rate), burst_(burst), tokens_(burst) {}

bool TokenBucket::take(Clock::time_point now) {
  if (started_ && now > last_) {
    tokens_ =
        std::min(burst_, tokens_ + std::chrono::duration<double>(now - last_).count() * rate_);
  }
  if (!started_ || now > last_) last_ = now;
  started_ = true;
  if (tokens_ < 1) return false;
  tokens_ -= 1;
  return true;
}

std::string format_trace_line(std::string_view bus, std::chrono::steady_clock::time_point at,
                              std::string_view node, TraceDirection direction,
                              std::string_view outcome, std::string_view bytes,
                              std::string_view label) {
  const auto us =
      std::chrono::duration_cast<std::chrono::microseconds>(at.time_since_epoch()).count();
  // One field each, so a script can split on spaces: "device error" -> device_error.
  std::string outcome_field = outcome.empty() ? "-" : std::string(outcome);
  std::replace(outcome_field.begin(), outcome_field.end(), ' ', '_');
  return fmt::format("trace {} ({}.{:06}) {} {} {} '{}'{}{}", bus, us / 1000000, us % 1000000,
                     node.empty() ? "-" : node, direction == TraceDirection::tx ? "tx" : "rx",
                     outcome_field, bytes, label.empty() ? "" : " ", label);
}

WireTrace::WireTrace(std::string bus, bool enabled, double rate, double burst)
    : bus_(std::move(bus)), enabled_(enabled), bucket_(rate, burst) {
  registry().push_back(this);
}

WireTrace::~WireTrace() {
  auto& r = registry();
  r.erase(std::remove(r.begin(), r.end(), this), r.end());
}

void WireTrace::set_enabled(bool on) {
  if (on == enabled_) return;
  enabled_ = on;
  log::notice("trace {}: {}", bus_, on ? "on" : "off");
}

void WireTrace::write(std::string_view line) {
  if (sink())
    sink()(line);
  else
    log::write(log::Level::info, line);
}

void WireTrace::emit(std::chrono::steady_clock::time_point at, std::string_view node,
                     TraceDirection direction, std::string_view outcome, std::string_view bytes,
                     std::string_view label) {
  if (observer()) observer()(TraceFrame{bus_, at, node, direction, outcome, bytes, label});
  if (!enabled_) return;
  if (!bucket_.take(at)) {
    ++dropped_;
    ++unreported_;
    return;
  }
  if (unreported_ > 0) {
    write(fmt::format("trace {}: {} line(s) dropped by the rate limit ({} in all)", bus_,
                      unreported_, dropped_));
    unreported_ = 0;
  }
  ++lines_;
  write(format_trace_line(bus_, at, node, direction, outcome, bytes, label));
}

void WireTrace::set_sink(Sink s) {
  sink() = std::move(s);
}

void WireTrace::set_observer(Observer o) {
  observer() = std::move(o);
}

bool WireTrace::observed() {
  return static_cast<bool>(observer());
}

std::vector<WireTrace*> WireTrace::all() {
  return registry();
}

int WireTrace::set(std::string_view bus, bool on) {
  int matched = 0;
  for (auto* t : registry())
    if (t->bus() == bus) {
      t->set_enabled(on);
      ++matched;
    }
  return matched;
}

bool WireTrace::toggle_all() {
  const auto& r = registry();
  const bool on = std::any_of(r.begin(), r.end(), [](const WireTrace* t) { return !t->enabled(); });
  for (auto* t : r) t->set_enabled(on);
  return on;
}

}  // namespace fieldgate

namespace fieldgate {

TraceControlResult trace_control(std::string_view target) {
  TraceControlResult result;
  const auto q = target.find('?');
  if (target.substr(0, q) != "/trace") return {404, "try /trace?bus=NAME&on=1\n"};
  std::optional<std::string> bus;
  std::optional<bool> on;
  std::string_view query = q == std::string_view::npos ? std::string_view{} : target.substr(q + 1);
  while (!query.empty()) {
    const auto amp = query.find('&');
    const auto pair = query.substr(0, amp);
    query = amp == std::string_view::npos ? std::string_view{} : query.substr(amp + 1);
    const auto eq = pair.find('=');
    const auto key = pair.substr(0, eq);
    const auto value = eq == std::string_view::npos ? std::string_view{} : pair.substr(eq + 1);
    if (key == "bus") {
      bus = std::string(value);
    } else if (key == "on") {
      if (value == "1" || value == "true")
        on = true;
      else if (value == "0" || value == "false")
        on = false;
      else
        return {400, fmt::format("on={}: give on=1 or on=0\n", value)};
    } else {
      return {400, fmt::format("unknown parameter '{}' (bus, on)\n", key)};
    }
  }
  if (!on) return {400, "give on=1 or on=0 (and bus=NAME, or every bus)\n"};
  if (bus) {
    if (WireTrace::set(*bus, *on) == 0) return {404, fmt::format("no bus '{}'\n", *bus)};
  } else {
    for (auto* t : WireTrace::all()) t->set_enabled(*on);
  }
  for (const auto* t : WireTrace::all())
    if (!bus || t->bus() == *bus)
      result.body += fmt::format("trace {}: {} ({} line(s), {} dropped)\n", t->bus(),
                                 t->enabled() ? "on" : "off", t->lines(), t->dropped());
  return result;
}

}  // namespace fieldgate
