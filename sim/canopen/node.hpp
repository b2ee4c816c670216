// One simulated CANopen node: CiA 301 communication (NMT, boot-up, heartbeat, node guarding,
// SDO server, EMCY, TPDO1) around a CiA 402 drive. Frames come in through receive(), go out
// through the sink, and time moves only when the caller passes it in.
#pragma once

#include "can_frame.hpp"
#include "drive402.hpp"
#include "object_dictionary.hpp"
#include "sdo_server.hpp"

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace fieldgate::sim::canopen {

enum class NmtState : std::uint8_t {
  initialising = 0x00,
  stopped = 0x04,
  operational = 0x05,
  pre_operational = 0x7F,
};
const char* to_string(NmtState state);

namespace cob {
constexpr std::uint32_t nmt = 0x000;
constexpr std::uint32_t emcy = 0x080;
constexpr std::uint32_t tpdo1 = 0x180;
constexpr std::uint32_t sdo_tx = 0x580;  // server to client
constexpr std::uint32_t sdo_rx = 0x600;  // client to server
constexpr std::uint32_t nmt_error_control = 0x700;
}  // namespace cob

namespace nmt_cs {
constexpr std::uint8_t start = 0x01;
constexpr std::uint8_t stop = 0x02;
constexpr std::uint8_t enter_pre_operational = 0x80;
constexpr std::uint8_t reset_node = 0x81;
constexpr std::uint8_t reset_communication = 0x82;
}  // namespace nmt_cs

// How the node's heartbeat producer behaves.
enum class HeartbeatObject {
  normal,  // 0x1017 read/write, heartbeat every 0x1017 ms (none while 0)
  absent,  // no 0x1017 (abort 0x06020000): a node-guarding-only device
  silent,  // 0x1017 takes writes, yet no heartbeat is ever sent
};

struct NodeConfig {
  // 0x1017 at power-up: 0, the CiA 301 default, sends no heartbeat until a master sets it.
  std::uint16_t heartbeat_ms = 0;
  HeartbeatObject heartbeat_object = HeartbeatObject::normal;
  bool node_guarding = true;  // answers an RTR on 0x700+id with its state and the toggle bit
  // NMT start is refused while the error register is set: the node stays pre-operational.
  bool start_needs_no_error = false;
  // An error the node powers up with (error register, 0x603F, 0x1003, EMCY after boot-up,
  // drive in Fault); 0 = none. Cleared by a CiA 402 fault reset.
  std::uint16_t power_up_error = 0;
  std::uint16_t tpdo_event_ms = 100;       // 0x1800:5 default
  std::uint16_t tpdo_inhibit_100us = 100;  // 0x1800:3 default (10 ms)
  std::chrono::milliseconds sdo_timeout{1000};
  std::string device_name = "fieldgate sim CiA 402 drive";
  // 0x1008 is optional in CiA 301; without it an upload is aborted with 0x06020000 (CANopenNode's
  // canopend ships without one).
  bool device_name_object = true;
  std::string hardware_version = "sim";
  std::string software_version = "fieldgate-sim-canopen 0.1";
  std::uint32_t vendor_id = 0x00F1E1D6;
  std::uint32_t product_code = 0x00000402;
  std::uint32_t revision = 0x00010000;
  std::uint32_t serial_base = 0x51000000;  // serial number = base + node ID
  DriveConfig drive;
};

// 0x1000: CiA 402 profile, additional information "servo drive".
constexpr std::uint32_t kDeviceType = 0x00020192;
// Manufacturer-specific objects of the simulator.
constexpr std::uint16_t kUserLabelIndex = 0x2000;    // RW string, segmented download target
constexpr std::uint16_t kFaultInjectIndex = 0x2001;  // WO u16: write an error code to fault

class Node {
 public:
  Node(std::uint8_t id, NodeConfig config, FrameSink sink, LogSink log = {});
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  std::uint8_t id() const { return id_; }
  bool powered() const { return powered_; }
  NmtState nmt_state() const { return nmt_; }
  const Drive402& drive() const { return drive_; }
  ObjectDictionary& od() { return od_; }
  std::uint8_t error_register() const { return error_register_; }
  std::uint16_t heartbeat_ms() const { return heartbeat_ms_; }

  // Power-on: boot-up message, then pre-operational.
  void power_on(TimePoint now);
  // Silent from now on, as if unplugged; everything not stored is lost.
  void power_off();

  void receive(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  // The latest time advance() must be called at to send what is due; max() when nothing is.
  TimePoint next_deadline() const;

  // Sets the error register and 0x603F, sends EMCY, puts the drive into Fault.
  void inject_fault(std::uint16_t code, TimePoint now);

 private:
  bool produces_heartbeat() const {
    return heartbeat_ms_ > 0 && config_.heartbeat_object == HeartbeatObject::normal;
  }

 public:
 private:
  void build_od();
  void boot(TimePoint now, bool reset_application);
  void set_nmt(NmtState state);
  void on_nmt(std::uint8_t command, TimePoint now);
  void on_sdo(const CanFrame& frame, TimePoint now);
  void send(std::uint32_t cob_id, std::initializer_list<std::uint8_t> bytes);
  void send_emcy(std::uint16_t code);
  void service_tpdo(TimePoint now);
  std::array<std::uint8_t, 6> tpdo1_payload() const;
  void log(const std::string& text) const;

  std::uint8_t id_;
  NodeConfig config_;
  FrameSink sink_;
  LogSink log_;
  ObjectDictionary od_;
  SdoServer sdo_;
  Drive402 drive_;

  bool powered_ = false;
  NmtState nmt_ = NmtState::initialising;
  TimePoint now_{};

  // Communication parameters (reset by NMT reset communication).
  std::uint16_t heartbeat_ms_ = 0;
  std::uint16_t tpdo_event_ms_ = 0;
  std::uint16_t tpdo_inhibit_100us_ = 0;
  TimePoint next_heartbeat_{};
  bool guard_toggle_ = false;

  std::optional<std::array<std::uint8_t, 6>> tpdo_last_;
  TimePoint tpdo_last_time_{};

  // Application state (reset by NMT reset node).
  std::uint8_t error_register_ = 0;
  std::uint16_t error_code_ = 0;              // 0x603F
  std::vector<std::uint32_t> error_history_;  // 0x1003, newest first
  std::string user_label_;
  std::uint16_t controlword_ = 0;
  std::uint16_t fault_inject_ = 0;

  // OD copies of constants and mirrors that must stay addressable.
  std::string device_name_, hardware_version_, software_version_;
};

}  // namespace fieldgate::sim::canopen
