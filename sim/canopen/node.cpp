#include "node.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <utility>

namespace fieldgate::sim::canopen {

namespace {

// CiA 301 error register bits for an emergency error code's class.
std::uint8_t error_register_bits(std::uint16_t code) {
  // By the code's first hex digit: current, voltage, temperature, communication, manufacturer
  // specific; every error sets the generic bit.
  static constexpr std::pair<unsigned, std::uint8_t> kClassBits[] = {
      {0x2, 0x02}, {0x3, 0x04}, {0x4, 0x08}, {0x8, 0x10}, {0xF, 0x80}};
  std::uint8_t reg = 0x01;
  for (const auto& [error_class, bit] : kClassBits)
    if (static_cast<unsigned>(code >> 12) == error_class) reg |= bit;
  return reg;
}

template <class T>
std::function<SdoAbort(T)> positive(T& var) {
  return [&var](T value) {
    if (value == 0) return SdoAbort::value_too_low;
    var = value;
    return SdoAbort::none;
  };
}

constexpr std::size_t kErrorHistoryLength = 4;

}  // namespace

const char* to_string(NmtState state) {
  switch (state) {
    case NmtState::initialising:
      return "initialising";
    case NmtState::stopped:
      return "stopped";
    case NmtState::operational:
      return "operational";
    case NmtState::pre_operational:
      return "pre-operational";
  }
  return "?";
}

Node::Node(std::uint8_t id, NodeConfig config, FrameSink sink, LogSink log)
    : id_(id),
      config_(std::move(config)),
      sink_(std::move(sink)),
      log_(std::move(log)),
      sdo_(od_, config_.sdo_timeout),
      drive_(config_.drive),
      device_name_(config_.device_name),
      hardware_version_(config_.hardware_version),
      software_version_(config_.software_version) {
  if (log_) drive_.log = [this](const std::string& text) { this->log(text); };
  build_od();
}

void Node::log(const std::string& text) const {
  if (log_) log_(fmt::format("node {}: {}", id_, text));
}

void Node::build_od() {
  auto computed = [this](std::uint16_t index, std::uint8_t sub, std::string name, auto fn) {
    OdEntry e;
    e.name = std::move(name);
    e.access = Access::ro;
    e.size = sizeof(fn());
    e.read = [fn] { return to_le(fn()); };
    od_.add(index, sub, std::move(e));
  };
  auto& p = drive_.params;

  od_.add_const<std::uint32_t>(0x1000, 0, "device type", kDeviceType);
  od_.add_value<std::uint8_t>(0x1001, 0, "error register", Access::ro, error_register_);
  {
    // Sub 0 is writable with 0 only, which clears the history (CiA 301 7.5.2.3).
    OdEntry e;
    e.name = "number of errors";
    e.access = Access::rw;
    e.size = 1;
    e.read = [this] { return to_le(static_cast<std::uint8_t>(error_history_.size())); };
    e.write = [this](std::span<const std::uint8_t> data) {
      if (data[0] != 0) return SdoAbort::value_range;
      error_history_.clear();
      return SdoAbort::none;
    };
    od_.add(0x1003, 0, std::move(e));
  }
  for (std::uint8_t sub = 1; sub <= kErrorHistoryLength; ++sub)
    computed(0x1003, sub, "standard error field", [this, sub]() -> std::uint32_t {
      return sub <= error_history_.size() ? error_history_[sub - 1] : 0;
    });
  if (config_.device_name_object)
    od_.add_string(0x1008, 0, "manufacturer device name", device_name_);
  od_.add_string(0x1009, 0, "manufacturer hardware version", hardware_version_);
  od_.add_string(0x100A, 0, "manufacturer software version", software_version_);
  od_.add_const<std::uint32_t>(0x1014, 0, "COB-ID EMCY", cob::emcy + id_);
  if (config_.heartbeat_object != HeartbeatObject::absent)
    od_.add_value<std::uint16_t>(0x1017, 0, "producer heartbeat time", Access::rw, heartbeat_ms_,
                                 [this](std::uint16_t ms) {
                                   heartbeat_ms_ = ms;
                                   next_heartbeat_ = now_ + std::chrono::milliseconds(ms);
                                   return SdoAbort::none;
                                 });
  od_.add_const<std::uint8_t>(0x1018, 0, "identity: highest sub-index", 4);
  od_.add_const<std::uint32_t>(0x1018, 1, "vendor-ID", config_.vendor_id);
  od_.add_const<std::uint32_t>(0x1018, 2, "product code", config_.product_code);
  od_.add_const<std::uint32_t>(0x1018, 3, "revision number", config_.revision);
  od_.add_const<std::uint32_t>(0x1018, 4, "serial number", config_.serial_base + id_);

  od_.add_const<std::uint8_t>(0x1800, 0, "TPDO1: highest sub-index", 5);
  od_.add_const<std::uint32_t>(0x1800, 1, "TPDO1 COB-ID", cob::tpdo1 + id_);
  od_.add_const<std::uint8_t>(0x1800, 2, "TPDO1 transmission type", 0xFF);
  od_.add_value<std::uint16_t>(0x1800, 3, "TPDO1 inhibit time (100 us)", Access::rw,
                               tpdo_inhibit_100us_);
  od_.add_value<std::uint16_t>(0x1800, 5, "TPDO1 event timer (ms)", Access::rw, tpdo_event_ms_);
  od_.add_const<std::uint8_t>(0x1A00, 0, "TPDO1 mapping: entries", 2);
  od_.add_const<std::uint32_t>(0x1A00, 1, "TPDO1 mapping 1", 0x60410010);
  od_.add_const<std::uint32_t>(0x1A00, 2, "TPDO1 mapping 2", 0x60640020);

  od_.add_string(kUserLabelIndex, 0, "user label", user_label_, 64);
  od_.add_value<std::uint16_t>(kFaultInjectIndex, 0, "simulator: inject fault", Access::wo,
                               fault_inject_, [this](std::uint16_t code) {
                                 if (code == 0) return SdoAbort::value_range;
                                 inject_fault(code, now_);
                                 return SdoAbort::none;
                               });

  od_.add_value<std::uint16_t>(0x603F, 0, "error code", Access::ro, error_code_);
  od_.add_value<std::uint16_t>(0x6040, 0, "controlword", Access::rw, controlword_,
                               [this](std::uint16_t cw) {
                                 controlword_ = cw;
                                 if (drive_.set_controlword(cw, now_)) {
                                   error_register_ = 0;
                                   error_code_ = 0;
                                   send_emcy(0x0000);
                                   log("fault reset");
                                 }
                                 return SdoAbort::none;
                               });
  computed(0x6041, 0, "statusword", [this] { return drive_.statusword(); });
  od_.add_value<std::int16_t>(0x605A, 0, "quick stop option code", Access::rw, p.quick_stop_option,
                              [&p](std::int16_t v) {
                                if (v < 0 || v > 8 || v == 3 || v == 4 || v == 7 || v == 8)
                                  return SdoAbort::value_range;
                                p.quick_stop_option = v;
                                return SdoAbort::none;
                              });
  od_.add_value<std::int8_t>(0x6060, 0, "modes of operation", Access::rw, p.mode,
                             [this](std::int8_t m) { return drive_.set_mode(m, now_); });
  computed(0x6061, 0, "modes of operation display", [this] { return drive_.mode_display(); });
  computed(0x6064, 0, "position actual value", [this] { return drive_.position_actual(); });
  computed(0x606C, 0, "velocity actual value", [this] { return drive_.velocity_actual(); });
  od_.add_value<std::int32_t>(0x607A, 0, "target position", Access::rw, p.target_position);
  od_.add_value<std::int32_t>(0x607C, 0, "home offset", Access::rw, p.home_offset);
  od_.add_value<std::uint32_t>(0x6081, 0, "profile velocity", Access::rw, p.profile_velocity,
                               positive(p.profile_velocity));
  od_.add_value<std::uint32_t>(0x6083, 0, "profile acceleration", Access::rw,
                               p.profile_acceleration, positive(p.profile_acceleration));
  od_.add_value<std::uint32_t>(0x6084, 0, "profile deceleration", Access::rw,
                               p.profile_deceleration, positive(p.profile_deceleration));
  od_.add_value<std::uint32_t>(0x6085, 0, "quick stop deceleration", Access::rw,
                               p.quick_stop_deceleration, positive(p.quick_stop_deceleration));
  od_.add_value<std::int8_t>(0x6098, 0, "homing method", Access::rw, p.homing_method);
  od_.add_const<std::uint8_t>(0x6099, 0, "homing speeds: highest sub-index", 2);
  od_.add_value<std::uint32_t>(0x6099, 1, "speed during search for switch", Access::rw,
                               p.homing_speed_switch, positive(p.homing_speed_switch));
  od_.add_value<std::uint32_t>(0x6099, 2, "speed during search for zero", Access::rw,
                               p.homing_speed_zero, positive(p.homing_speed_zero));
  od_.add_value<std::uint32_t>(0x609A, 0, "homing acceleration", Access::rw, p.homing_acceleration,
                               positive(p.homing_acceleration));
  od_.add_const<std::uint32_t>(0x6502, 0, "supported drive modes", 0x00000021);  // pp, hm
}

void Node::power_on(TimePoint now) {
  if (powered_) return;
  powered_ = true;
  log("power on");
  boot(now, true);
}

void Node::power_off() {
  if (!powered_) return;
  powered_ = false;
  nmt_ = NmtState::initialising;
  log("power off");
}

void Node::boot(TimePoint now, bool reset_application) {
  now_ = now;
  if (reset_application) {
    drive_.reset(now);
    controlword_ = 0;
    error_register_ = 0;
    error_code_ = 0;
    error_history_.clear();
    user_label_ = fmt::format("axis {}", id_);
  }
  heartbeat_ms_ = config_.heartbeat_ms;
  tpdo_event_ms_ = config_.tpdo_event_ms;
  tpdo_inhibit_100us_ = config_.tpdo_inhibit_100us;
  sdo_.reset();
  guard_toggle_ = false;
  tpdo_last_.reset();
  set_nmt(NmtState::initialising);
  send(cob::nmt_error_control + id_, {0x00});
  set_nmt(NmtState::pre_operational);
  next_heartbeat_ = now + std::chrono::milliseconds(heartbeat_ms_);
  if (reset_application && config_.power_up_error != 0) inject_fault(config_.power_up_error, now);
}

void Node::set_nmt(NmtState state) {
  if (state == nmt_) return;
  if (nmt_ != NmtState::initialising || state != NmtState::pre_operational)
    log(fmt::format("NMT {} -> {}", to_string(nmt_), to_string(state)));
  nmt_ = state;
  if (state == NmtState::operational) tpdo_last_.reset();
  if (state == NmtState::stopped) sdo_.reset();
}

void Node::send(std::uint32_t cob_id, std::initializer_list<std::uint8_t> bytes) {
  sink_(CanFrame::make(cob_id, bytes));
}

void Node::send_emcy(std::uint16_t code) {
  if (nmt_ != NmtState::pre_operational && nmt_ != NmtState::operational) return;
  send(cob::emcy + id_, {static_cast<std::uint8_t>(code), static_cast<std::uint8_t>(code >> 8),
                         error_register_, 0, 0, 0, 0, 0});
}

void Node::inject_fault(std::uint16_t code, TimePoint now) {
  if (!powered_) return;
  advance(now);
  error_code_ = code;
  error_register_ = error_register_bits(code);
  error_history_.insert(error_history_.begin(), code);
  if (error_history_.size() > kErrorHistoryLength) error_history_.resize(kErrorHistoryLength);
  log(fmt::format("fault 0x{:04X}", code));
  drive_.fault(now);
  send_emcy(code);
  service_tpdo(now);
}

void Node::receive(const CanFrame& frame, TimePoint now) {
  if (!powered_) return;
  advance(now);
  if (frame.rtr) {
    // Node guarding: state with a toggle bit that alternates per reply.
    if (frame.id == cob::nmt_error_control + id_ && config_.node_guarding) {
      send(cob::nmt_error_control + id_,
           {static_cast<std::uint8_t>((guard_toggle_ ? 0x80 : 0) |
                                      static_cast<std::uint8_t>(nmt_))});
      guard_toggle_ = !guard_toggle_;
    }
    return;
  }
  if (frame.id == cob::nmt) {
    if (frame.len >= 2 && (frame.data[1] == 0 || frame.data[1] == id_)) on_nmt(frame.data[0], now);
  } else if (frame.id == cob::sdo_rx + id_) {
    on_sdo(frame, now);
  }
  if (powered_) service_tpdo(now);
}

void Node::on_nmt(std::uint8_t command, TimePoint now) {
  switch (command) {
    case nmt_cs::start:
      if (config_.start_needs_no_error && error_register_ != 0 && nmt_ != NmtState::operational) {
        log(fmt::format("NMT start refused: error register 0x{:02X}", error_register_));
        break;
      }
      set_nmt(NmtState::operational);
      break;
    case nmt_cs::stop:
      set_nmt(NmtState::stopped);
      break;
    case nmt_cs::enter_pre_operational:
      set_nmt(NmtState::pre_operational);
      break;
    case nmt_cs::reset_node:
      log("NMT reset node");
      boot(now, true);
      break;
    case nmt_cs::reset_communication:
      log("NMT reset communication");
      boot(now, false);
      break;
    default:
      break;
  }
}

void Node::on_sdo(const CanFrame& frame, TimePoint now) {
  if (nmt_ != NmtState::pre_operational && nmt_ != NmtState::operational) return;
  // CiA 301 SDO frames always carry 8 bytes; like most stacks, shorter ones are ignored.
  if (frame.len != 8) {
    log(fmt::format("ignoring SDO request with DLC {}", frame.len));
    return;
  }
  if (auto reply = sdo_.on_request(frame.data, now)) {
    CanFrame out;
    out.id = cob::sdo_tx + id_;
    out.len = 8;
    out.data = *reply;
    sink_(out);
  }
}

std::array<std::uint8_t, 6> Node::tpdo1_payload() const {
  const std::uint16_t sw = drive_.statusword();
  const auto pos = static_cast<std::uint32_t>(drive_.position_actual());
  return {static_cast<std::uint8_t>(sw),        static_cast<std::uint8_t>(sw >> 8),
          static_cast<std::uint8_t>(pos),       static_cast<std::uint8_t>(pos >> 8),
          static_cast<std::uint8_t>(pos >> 16), static_cast<std::uint8_t>(pos >> 24)};
}

void Node::service_tpdo(TimePoint now) {
  if (nmt_ != NmtState::operational) return;
  const auto payload = tpdo1_payload();
  const auto inhibit = std::chrono::microseconds(100) * tpdo_inhibit_100us_;
  const auto event = std::chrono::milliseconds(tpdo_event_ms_);
  const bool due = !tpdo_last_ || (payload != *tpdo_last_ && now >= tpdo_last_time_ + inhibit) ||
                   (tpdo_event_ms_ > 0 && now >= tpdo_last_time_ + event);
  if (!due) return;
  CanFrame frame;
  frame.id = cob::tpdo1 + id_;
  frame.len = 6;
  std::copy(payload.begin(), payload.end(), frame.data.begin());
  sink_(frame);
  tpdo_last_ = payload;
  tpdo_last_time_ = now;
}

void Node::advance(TimePoint now) {
  if (!powered_) return;
  now_ = now;
  drive_.advance(now);
  if (auto reply = sdo_.on_time(now)) {
    CanFrame out;
    out.id = cob::sdo_tx + id_;
    out.len = 8;
    out.data = *reply;
    sink_(out);
  }
  if (produces_heartbeat() && now >= next_heartbeat_) {
    send(cob::nmt_error_control + id_, {static_cast<std::uint8_t>(nmt_)});
    const auto period = std::chrono::milliseconds(heartbeat_ms_);
    next_heartbeat_ += period;
    if (next_heartbeat_ <= now) next_heartbeat_ = now + period;
  }
  service_tpdo(now);
}

TimePoint Node::next_deadline() const {
  TimePoint t = TimePoint::max();
  if (!powered_) return t;
  if (produces_heartbeat()) t = std::min(t, next_heartbeat_);
  if (auto d = sdo_.deadline()) t = std::min(t, *d);
  if (auto d = drive_.deadline()) t = std::min(t, *d);
  if (nmt_ == NmtState::operational) {
    if (tpdo_event_ms_ > 0)
      t = std::min(t, tpdo_last_time_ + std::chrono::milliseconds(tpdo_event_ms_));
    // While moving, look again after the inhibit time even if the rounded position has not
    // changed yet; never at the time just served, which would spin the caller's loop.
    if (drive_.moving() || !tpdo_last_ || tpdo1_payload() != *tpdo_last_) {
      const auto inhibit = std::chrono::microseconds(100) * tpdo_inhibit_100us_;
      t = std::min(t, std::max(tpdo_last_time_ + inhibit, now_ + std::chrono::milliseconds(1)));
    }
  }
  return t;
}

}  // namespace fieldgate::sim::canopen
