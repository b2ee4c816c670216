#include "drivers/canopen/node_supervision.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fieldgate::canopen {

namespace {
// Syslog levels of NodeHost::log.
constexpr int kWarning = 4;
constexpr int kNotice = 5;
constexpr int kInfo = 6;
// The consumer time is this many producer times, as in Lely's dcfgen (heartbeat_multiplier):
// two heartbeats may be lost before the node counts as gone.
constexpr int kHeartbeatMultiplier = 3;

int64_t milliseconds(std::chrono::microseconds t) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(t).count();
}
}  // namespace

std::string error_register_text(uint8_t reg) {
  static constexpr const char* kBits[] = {
      "generic",       "current",        "voltage",  "temperature",
      "communication", "device profile", "reserved", "manufacturer-specific"};
  std::string text;
  for (int bit = 0; bit < 8; ++bit)
    if (reg & (1u << bit)) text += (text.empty() ? "" : ", ") + std::string(kBits[bit]);
  return text.empty() ? "no error" : text;
}

NodeSupervision::NodeSupervision(uint8_t id, std::string name, const SupervisionTiming& timing,
                                 NodeHost& host)
    : id_(id), name_(std::move(name)), timing_(timing), host_(host) {}

std::string NodeSupervision::who() const {
  return fmt::format("{} ({})", name_, id_);
}

uint16_t NodeSupervision::producer_ms() const {
  if (chosen_producer_ms_) return *chosen_producer_ms_;
  const auto ms = milliseconds(timing_.heartbeat_timeout) / kHeartbeatMultiplier;
  return static_cast<uint16_t>(std::clamp<int64_t>(ms, 1, 0xFFFF));
}

std::chrono::microseconds NodeSupervision::consumer_time() const {
  if (!chosen_producer_ms_ || *chosen_producer_ms_ == 0) return timing_.heartbeat_timeout;
  return std::chrono::milliseconds(*chosen_producer_ms_) * kHeartbeatMultiplier;
}

NodeSupervision::Duty NodeSupervision::duty(bool reachable) const {
  // A stopped node answers no SDO: where it is to be started, the start goes first.
  const bool stopped = status_.nmt_state == nmt_state::stopped;
  if (configure_pending_ && reachable && !(stopped && start_pending_)) return Duty::configure;
  if (start_pending_ && (!configure_pending_ || stopped)) return Duty::start;
  if (pre_operational_check_ && reachable) return Duty::report_pre_operational;
  if (next_guard_ != TimePoint::max() && reachable) return Duty::guard;
  return Duty::none;
}

void NodeSupervision::bring_up(bool start) {
  configure_pending_ = consumer();
  status_.liveness = Liveness::sdo;  // until a heartbeat follows the configuration
  heartbeat_deadline_ = TimePoint::max();
  heartbeat_seen_ = false;
  start_pending_ = start && timing_.start_nodes;
  start_sent_.reset();
  pre_operational_check_ = false;
  stuck_error_register_.reset();
  status_.stays_pre_operational = false;
  stop_guarding();
  host_.wake_worker();
}

void NodeSupervision::link_lost() {
  offline_by_heartbeat_ = consumer();
}

void NodeSupervision::sdo_silent() {
  offline_by_heartbeat_ = false;
}

void NodeSupervision::went_online(bool from_offline) {
  offline_by_heartbeat_ = false;
  // Back from offline, it may have restarted unseen: configure it again, then NMT start.
  if (from_offline) bring_up(true);
}

void NodeSupervision::went_offline() {
  heartbeat_deadline_ = TimePoint::max();
  pre_operational_check_ = false;
}

void NodeSupervision::on_heartbeat(uint8_t state, bool toggle, TimePoint now) {
  const auto previous = status_.nmt_state;
  status_.nmt_state = state;
  if (state == nmt_state::boot_up) {
    last_boot_up_ = now;
    if (host_.presence() == Presence::online)
      host_.log(kWarning, fmt::format("node {} sent boot-up: it restarted", who()));
    host_.probe_by(now);
    bring_up(true);         // its 0x1017 is back at its default
    guard_toggle_.reset();  // its next guard reply carries 0, like a heartbeat: not counted
    if (consumer()) host_.go_online();
  } else {
    const bool heartbeat = !take_guard_reply(toggle);
    if (heartbeat) heartbeat_while_guarding(now);
    // The consumer is armed once the producer time is configured (and not given up on).
    if (heartbeat && consumer() && heartbeat_deadline_ != TimePoint::max()) {
      if (!heartbeat_seen_) {
        heartbeat_seen_ = true;
        status_.liveness = Liveness::heartbeat;
        stop_guarding();  // the heartbeat tells the NMT state now
      }
      heartbeat_deadline_ = now + consumer_time();
    }
    const auto presence = host_.presence();
    if (presence == Presence::offline) {
      if (consumer() && offline_by_heartbeat_) {
        host_.go_online();
        if (state == nmt_state::operational) start_pending_ = false;
      } else {
        host_.probe_by(now);  // it is there: probe now
      }
    } else if (presence == Presence::starting && consumer()) {
      host_.go_online();
    }
    if (state == nmt_state::operational) {
      if (status_.stays_pre_operational)
        host_.log(kNotice, fmt::format("node {} is operational now", who()));
      status_.stays_pre_operational = false;
      stuck_error_register_.reset();
      start_sent_.reset();
    } else if (state == nmt_state::pre_operational && start_sent_ && !start_pending_ &&
               !status_.stays_pre_operational && !pre_operational_check_) {
      // A heartbeat sent after the node had time to carry out the start.
      const auto grace = std::max<TimePoint::duration>(timing_.reply_timeout,
                                                       std::chrono::milliseconds(producer_ms()));
      if (now - *start_sent_ >= grace) pre_operational_check_ = true;
    }
  }
  if (previous != state) {
    host_.log(kInfo, fmt::format("node {} NMT state {}", name_, nmt_state_text(state)));
    host_.refresh_local_points(now);
  }
  if (start_pending_ || pre_operational_check_ || host_.presence() == Presence::offline)
    host_.wake_worker();
}

void NodeSupervision::on_emergency(const Emergency& e) {
  status_.emcy_code = e.code;
  status_.emcy_register = e.error_register;
  ++status_.emergencies;
  if (e.code != 0) {
    std::string text = fmt::format("EMCY 0x{:04X} ({}), error register 0x{:02X}", e.code,
                                   emergency_text(e.code), e.error_register);
    host_.log(kWarning, fmt::format("node {}: {}", name_, text));
    host_.device_error(e.code, std::move(text));
  } else {
    host_.log(kNotice, fmt::format("node {}: EMCY error reset", name_));
    error_register_seen(e.error_register);
  }
  host_.refresh_local_points(host_.now());
}

bool NodeSupervision::on_downloaded(const ObjectAddress& object, int64_t value, TimePoint at,
                                    bool by_command) {
  if (!consumer() || object.index != kHeartbeatObject.index || object.sub != kHeartbeatObject.sub)
    return false;
  if (by_command) {
    chosen_producer_ms_ = static_cast<uint16_t>(std::clamp<int64_t>(value, 0, 0xFFFF));
    host_.log(kNotice,
              value > 0
                  ? fmt::format("node {} heartbeat producer time 0x1017 written by a command: "
                                "{} ms; consumer time {} ms from now on",
                                who(), value, milliseconds(consumer_time()))
                  : fmt::format("node {} heartbeat producer time 0x1017 written by a command: "
                                "0 (no heartbeat); liveness by SDO from now on",
                                who()));
  }
  // A new producer time (ours or a PLC's): a heartbeat must follow within the consumer time, or
  // the node is one without (a PLC wrote 0): SDO liveness, never a false loss.
  heartbeat_seen_ = false;
  written_producer_ms_ = value;
  status_.liveness = Liveness::sdo;
  if (value == 0) {
    watch_by_sdo(at);  // no heartbeat is to come
    return true;
  }
  heartbeat_deadline_ = at + consumer_time();
  // A heartbeat is to come: node guarding stops (it starts again if none comes). Its answers
  // share the heartbeat's COB-ID and would be taken for the heartbeat.
  stop_guarding();
  return true;
}

void NodeSupervision::error_register_seen(uint8_t reg) {
  if (reg != 0 || !stuck_error_register_ || *stuck_error_register_ == 0) return;
  host_.log(kNotice, fmt::format("node {} error register cleared: NMT start again", who()));
  stuck_error_register_.reset();  // once: if it stays pre-operational, that is reported
  status_.stays_pre_operational = false;
  start_pending_ = timing_.start_nodes;
  host_.wake_worker();
}

TimePoint NodeSupervision::check_heartbeat(TimePoint now) {
  if (now >= heartbeat_deadline_ && !heartbeat_seen_) {
    // The producer time was accepted, yet nothing came: this node has no working heartbeat
    // producer. Its SDO answers tell whether it is there, never a deadline.
    watch_by_sdo(now);
    host_.log(kWarning,
              fmt::format("node {} sent no heartbeat within {} ms of its producer time 0x1017 "
                          "being set to {} ms; liveness by SDO from now on (offline after {} SDO "
                          "timeouts)",
                          who(), milliseconds(consumer_time()), written_producer_ms_,
                          timing_.offline_after));
    return TimePoint::max();
  }
  if (now >= heartbeat_deadline_) {
    offline_by_heartbeat_ = true;
    host_.go_offline(fmt::format("no heartbeat within {} ms", milliseconds(consumer_time())));
    return TimePoint::max();
  }
  return heartbeat_deadline_;
}

void NodeSupervision::configured(const Reply& r, int64_t producer, TimePoint finished_at) {
  switch (r.status) {
    case Reply::Status::ok:  // on_downloaded() armed the consumer
      configure_pending_ = false;
      host_.log(kInfo,
                fmt::format("node {} heartbeat producer time 0x1017 set to {} ms "
                            "({}consumer {} ms)",
                            who(), producer, chosen_producer_ms_ ? "chosen by a command; " : "",
                            milliseconds(consumer_time())));
      break;
    case Reply::Status::device_error:
    case Reply::Status::garbled:
      configure_pending_ = false;
      watch_by_sdo(finished_at);
      host_.log(kWarning,
                fmt::format("node {} did not take heartbeat producer time 0x1017 = {} ms: {}; "
                            "liveness by SDO (offline after {} SDO timeouts)",
                            who(), producer, r.text, timing_.offline_after));
      break;
    default:
      // No answer: tried again while the node is online; after its timeouts it is offline,
      // and configured when it answers a probe.
      break;
  }
}

CanFrame NodeSupervision::start(TimePoint now) {
  start_pending_ = false;
  host_.log(kInfo, fmt::format("NMT start node {}", who()));
  start_sent_ = now;
  return nmt_frame(NmtCommand::start, id_);
}

void NodeSupervision::started_by_command(TimePoint now) {
  start_pending_ = false;
  start_sent_ = now;
}

void NodeSupervision::report_pre_operational(const Reply& r) {
  if (status_.nmt_state != nmt_state::pre_operational) return;  // it moved meanwhile
  status_.stays_pre_operational = true;
  std::string text;
  if (r.status == Reply::Status::ok && !r.values.empty()) {
    const auto reg = static_cast<uint8_t>(r.values[0]);
    stuck_error_register_ = reg;
    text = fmt::format("stays pre-operational after NMT start; error register 0x{:02X} ({})", reg,
                       error_register_text(reg));
  } else {
    text = fmt::format("stays pre-operational after NMT start; error register unread: {}",
                       r.text.empty() ? std::string(to_string(r.status)) : r.text);
  }
  host_.log(kWarning, fmt::format("node {} {}; not started again until its error register "
                                  "clears or it boots",
                                  who(), text));
  host_.error_text(std::move(text));
}

std::optional<CanFrame> NodeSupervision::guard(TimePoint now) {
  if (guard_paused_) {
    guard_paused_ = false;
    guarding_since_ = now;
    guard_answered_ = false;
    host_.log(kInfo, fmt::format("node {} sent no heartbeat within {} ms: node guarding again",
                                 who(), milliseconds(consumer_time())));
  }
  if (!guard_answered_ && now - *guarding_since_ >= consumer_time()) {
    next_guard_ = TimePoint::max();
    host_.log(
        kWarning,
        fmt::format("node {} answers no node guarding either: its NMT state is unknown", who()));
    status_.nmt_state.reset();
    host_.nmt_state_forgotten();
    return std::nullopt;
  }
  // Every producer time the consumer expects (a chosen 0 guards at the configured rate).
  next_guard_ = now + consumer_time() / kHeartbeatMultiplier;
  CanFrame rtr;
  rtr.id = cob::heartbeat + id_;
  rtr.len = 1;
  rtr.rtr = true;
  guard_outstanding_ = true;
  return rtr;
}

void NodeSupervision::stop_guarding() {
  next_guard_ = TimePoint::max();
  guarding_since_.reset();
  guard_answered_ = false;
  if (guard_outstanding_) guard_toggle_.reset();  // its reply may still come, unseen
  guard_outstanding_ = false;
  guard_paused_ = false;
}

bool NodeSupervision::take_guard_reply(bool toggle) {
  const bool asked = guarding_since_ && guard_outstanding_;
  // Toggle 0 where nothing was asked or 1 was due: a heartbeat.
  if (!toggle && (!asked || guard_toggle_ == true)) return false;
  if (asked) {
    // Where the toggle was unknown, the first reply only tells it: alone, a 0 looks like a
    // heartbeat. A 1 where 0 was due (another master's RTR, a reset unseen) is followed, not
    // counted.
    if (guard_toggle_ == toggle) {
      guard_answered_ = true;
      ++status_.guard_replies;
    }
    guard_outstanding_ = false;
  }
  // Only a guard reply has bit 7 set: after one, whoever asked for it, the next carries 0.
  guard_toggle_ = !toggle;
  return true;
}

void NodeSupervision::heartbeat_while_guarding(TimePoint now) {
  const bool guarding = guarding_since_ && next_guard_ != TimePoint::max();
  if (!guarding && !guard_paused_) return;
  if (!guard_paused_) {
    stop_guarding();
    guard_paused_ = true;
    host_.log(kInfo, fmt::format("node {} sends heartbeats the gateway did not set up: node "
                                 "guarding stops while they come",
                                 who()));
  }
  next_guard_ = now + consumer_time();
}

void NodeSupervision::watch_by_sdo(TimePoint now) {
  status_.liveness = Liveness::sdo;
  heartbeat_deadline_ = TimePoint::max();
  if (guarding_since_) return;
  guard_paused_ = false;
  guarding_since_ = now;
  guard_answered_ = false;
  next_guard_ = now;
  host_.wake_worker();
}

}  // namespace fieldgate::canopen
