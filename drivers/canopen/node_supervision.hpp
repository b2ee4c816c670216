// How the gateway watches one CANopen node and brings it up: the heartbeat consumer (CiA 301),
// node guarding where the node produces no heartbeat, the bring-up of CiA 302 practice (write
// the heartbeat producer time 0x1017, then NMT start), a node that stays pre-operational, and
// EMCY. No I/O and no clock of its own: the CAN bus runtime feeds it frames and transfer
// results, runs the transfers it asks for, and keeps the node's online/offline state behind
// NodeHost. The readings chosen are in README.md.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "drivers/canopen/canopen_codec.hpp"
#include "drivers/canopen/canopen_request.hpp"
#include "drivers/canopen/canopen_time.hpp"
#include "drivers/protocol_family.hpp"
#include "drivers/transport/can_frame.hpp"

namespace fieldgate::canopen {

// The device type, which every CiA 301 device has: the probe of an offline node.
inline const ObjectAddress kDeviceTypeObject{0x1000, 0, DataType::unsigned32};
inline const ObjectAddress kHeartbeatObject{0x1017, 0, DataType::unsigned16};
inline const ObjectAddress kErrorRegisterObject{0x1001, 0, DataType::unsigned8};

// The bits of the error register 0x1001 named ("generic, voltage"), or "no error".
std::string error_register_text(uint8_t reg);

// How the bus knows a node is alive: by its heartbeat (the consumer, after the bus set the
// node's producer time), or by its SDO answers where it produces no heartbeat.
enum class Liveness { heartbeat, sdo };

// What the bus consumed from a node, for diagnostics and tests.
struct NodeStatus {
  std::optional<uint8_t> nmt_state;  // from the last heartbeat
  Liveness liveness = Liveness::sdo;
  bool stays_pre_operational = false;  // NMT start sent, the node did not leave pre-op
  uint16_t emcy_code = 0;
  uint8_t emcy_register = 0;
  uint64_t emergencies = 0;
  uint32_t last_abort = 0;  // last SDO abort code the node sent
  uint64_t pdos = 0;        // TPDOs taken into the process image
  // Node-guarding replies taken: each answered an RTR of the bus with the toggle bit expected.
  uint64_t guard_replies = 0;
};

struct SupervisionTiming {
  std::chrono::microseconds heartbeat_timeout{0};  // the consumer time; 0: no consumer
  std::chrono::microseconds reply_timeout{0};
  bool start_nodes = false;
  int offline_after = 0;  // SDO timeouts before a node watched by SDO is offline (for logs)
};

// The node's place in the bus runtime.
enum class Presence { starting, online, offline, faulted };

// What the supervision asks of the bus runtime that hosts the node.
class NodeHost {
 public:
  virtual ~NodeHost() = default;
  virtual Presence presence() const = 0;
  virtual void go_online() = 0;
  virtual void go_offline(std::string why) = 0;
  // The node is there: an offline node is probed no later than `when`.
  virtual void probe_by(TimePoint when) = 0;
  // The node's local points (NMT state, EMCY, last abort) take the status's values.
  virtual void refresh_local_points(TimePoint now) = 0;
  // The NMT state is unknown now: its point holds no value.
  virtual void nmt_state_forgotten() = 0;
  virtual void device_error(uint16_t code, std::string text) = 0;
  virtual void error_text(std::string text) = 0;
  // Something for the node's worker to do (a start, a report, a probe).
  virtual void wake_worker() = 0;
  // A syslog level (3 error .. 7 debug) and the text after the bus's name.
  virtual void log(int level, std::string text) = 0;
  virtual TimePoint now() const = 0;
};

class NodeSupervision {
 public:
  NodeSupervision(uint8_t id, std::string name, const SupervisionTiming& timing, NodeHost& host);

  NodeStatus& status() { return status_; }
  const NodeStatus& status() const { return status_; }
  bool consumer() const { return timing_.heartbeat_timeout.count() > 0; }
  // The heartbeat producer time the bus writes at bring-up: the one a command chose for this
  // node (a PLC's confirmed write of 0x1017), else a third of the configured consumer time.
  uint16_t producer_ms() const;
  // The consumer time for this node: three producer times where a command chose the producer
  // time, else the configured heartbeat_timeout.
  std::chrono::microseconds consumer_time() const;

  // What the node's worker does next, before commands and polls.
  enum class Duty { none, configure, start, report_pre_operational, guard };
  Duty duty(bool reachable) const;
  TimePoint next_guard() const { return next_guard_; }

  // Link opened, boot-up, back from offline: configure the heartbeat, then NMT start.
  void bring_up(bool start);
  void link_lost();   // offline with the link
  void sdo_silent();  // offline by SDO timeouts; its heartbeat may go on meanwhile
  void went_online(bool from_offline);
  void went_offline();

  // A frame on the node's NMT error-control COB-ID (0x700 + id): boot-up, heartbeat or
  // node-guarding reply; `toggle` is its bit 7.
  void on_heartbeat(uint8_t state, bool toggle, TimePoint now);
  // The node sent a boot-up after `sent`: a request sent then was dropped by its restart, and its
  // timeout says nothing about the node now.
  bool restarted_since(TimePoint sent) const { return last_boot_up_ && *last_boot_up_ > sent; }
  void on_emergency(const Emergency& emcy);
  // A confirmed download, by a command or by the bus's own bring-up; true where it re-armed the
  // heartbeat consumer (0x1017 written). A command's producer time is the node's from then on.
  bool on_downloaded(const ObjectAddress& object, int64_t value, TimePoint at, bool by_command);
  // The error register as last read or sent: NMT start again when it cleared on a node that
  // stayed pre-operational with an error.
  void error_register_seen(uint8_t reg);
  // The consumer's check at `now`: the node's next heartbeat deadline, or TimePoint::max().
  TimePoint check_heartbeat(TimePoint now);

  // Duty::configure: the write of 0x1017 came out as `reply`.
  void configured(const Reply& reply, int64_t producer, TimePoint finished_at);
  // Duty::start: the frame to send.
  CanFrame start(TimePoint now);
  // NMT start sent by a command.
  void started_by_command(TimePoint now);
  // Duty::report_pre_operational: begun, then the error register's upload came out as `reply`.
  void begin_pre_operational_report() { pre_operational_check_ = false; }
  void report_pre_operational(const Reply& reply);
  // Duty::guard: the node-guarding request to send, or none once guarding is given up.
  std::optional<CanFrame> guard(TimePoint now);

 private:
  void watch_by_sdo(TimePoint now);
  void stop_guarding();
  // Takes a state frame as the reply to the outstanding guard RTR where its toggle bit is the
  // one expected; false where it is none (a heartbeat, or another master's guarding).
  bool take_guard_reply(bool toggle);
  // A heartbeat while the node is guarded: someone else set its producer time. Guarding waits
  // until none came for a consumer time.
  void heartbeat_while_guarding(TimePoint now);
  std::string who() const;  // "drive (2)"

  uint8_t id_;
  std::string name_;
  SupervisionTiming timing_;
  NodeHost& host_;
  NodeStatus status_;

  // Heartbeat consumer. The deadline is armed once the producer time is configured; until a
  // heartbeat follows, a passing deadline means the node produces none (SDO liveness), after
  // that it means the heartbeat was lost (offline).
  TimePoint heartbeat_deadline_ = TimePoint::max();
  bool heartbeat_seen_ = false;      // since the producer time was configured
  int64_t written_producer_ms_ = 0;  // the producer time last written
  // The producer time a command wrote: bring-up writes it again and the consumer follows it, so
  // a PLC's choice is neither overwritten nor taken for a lost heartbeat.
  std::optional<uint16_t> chosen_producer_ms_;
  bool offline_by_heartbeat_ = false;  // its heartbeat stopped; probed by SDO meanwhile
  bool configure_pending_ = false;     // 0x1017 to write (before NMT start)
  bool start_pending_ = false;         // NMT start to send
  // Node guarding, for the NMT state of a node watched by SDO: sent every producer time until
  // one consumer time passed without an answer (the node does not guard either).
  TimePoint next_guard_ = TimePoint::max();
  std::optional<TimePoint> guarding_since_;
  bool guard_answered_ = false;
  bool guard_outstanding_ = false;  // an RTR sent, its reply not yet taken
  // The toggle bit of the next guard reply (CiA 301: it alternates), learnt from the node's last
  // reply. Unknown until one came, after a boot-up (the next is 0, which a heartbeat looks like)
  // and after guarding stopped with a reply outstanding.
  std::optional<bool> guard_toggle_;
  // Heartbeats came while guarding (another tool set 0x1017): next_guard_ is when guarding
  // starts again, pushed on by every heartbeat.
  bool guard_paused_ = false;
  std::optional<TimePoint> last_boot_up_;
  // NMT start sent by the bus; a later pre-operational heartbeat means the node stayed there.
  std::optional<TimePoint> start_sent_;
  bool pre_operational_check_ = false;  // read its error register and report
  // The error register read when the node was found staying pre-operational: when it clears,
  // the bus sends NMT start once more.
  std::optional<uint8_t> stuck_error_register_;
};

}  // namespace fieldgate::canopen
