#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mapping/axis_profile.hpp"
#include "mapping/command_template.hpp"
#include "mapping/diagnostics.hpp"
#include "mapping/value_type.hpp"

namespace fieldgate {

// How a reply field is written on the wire; the family decodes it.
enum class NumberFormat { decimal, hex, hex24 };

// A CANopen object dictionary entry, for the canopen family.
struct ObjectRef {
  uint16_t index = 0;
  uint8_t subindex = 0;
  std::string data_type;  // CANopen data type name, e.g. INTEGER32
};

struct ReadSpec {
  CommandTemplate request;  // without node addressing; the family adds it
  int field = 0;            // which value of a multi-value reply
  NumberFormat format = NumberFormat::decimal;
  std::optional<ObjectRef> object;
};

struct WriteSpec {
  CommandTemplate request;  // {value} is the value written
  std::optional<ObjectRef> object;
};

struct BitDef {
  std::string name;
  int bit = 0;
};

struct PointDef {
  std::string name;
  std::string description;
  ValueType type = ValueType::int32;
  std::string units;
  double scale = 1.0;  // engineering units per raw count, for documentation
  std::optional<ReadSpec> read;
  std::optional<WriteSpec> write;
  std::string poll_class;  // empty: never polled (write-only)
  std::vector<BitDef> bits;
  std::optional<int64_t> min;
  std::optional<int64_t> max;
  // The value the controller takes as "none" (a frequency source 0 that never moves): a profile
  // motion command refuses to send it as its speed.
  std::optional<int64_t> none;
  SourceMark mark;

  bool readable() const { return read.has_value(); }
  bool writable() const { return write.has_value(); }
  const BitDef* find_bit(const std::string& bit_name) const;
};

// A gateway-local parameter of actions (target, speed): written by the PLC, never sent on its
// own, substituted into action steps.
struct SetpointDef {
  std::string name;
  std::string description;
  ValueType type = ValueType::int32;
  std::string units;
  double scale = 1.0;
  int64_t default_value = 0;
  std::optional<int64_t> min;
  std::optional<int64_t> max;
  std::optional<int64_t> none;  // as PointDef::none
  SourceMark mark;
};

// done/failed test of an action against a polled point, optionally a single bit of it.
struct Condition {
  std::string point;
  std::optional<int> bit;
  int64_t equals = 0;
  // For a failed condition: the point whose value becomes the action's error code (a device
  // code the family reports), instead of the generic failed-condition code.
  std::string error_from;
};

struct ActionStep {
  enum class Kind { send, delay };
  Kind kind = Kind::send;
  CommandTemplate command;
  std::chrono::microseconds duration{0};
  // Device error codes that count as success for this step (e.g. Copley's e 32 after a remote
  // reset), and whether no reply at all counts as success.
  std::vector<int> accept_errors;
  bool accept_no_reply = false;
  bool urgent = false;  // sent at once, not queued behind a transaction holding the line
  // Confirms the Modbus write once this step has been on the wire for this long without a reply
  // (a reply that comes sooner, e.g. an error, answers the write as usual). For commands whose
  // handshake only comes at the end of a motion: the action stays busy until the reply arrives
  // and then goes on (later steps, done/failed watch) or ends in error with the reply's code.
  std::optional<std::chrono::microseconds> confirm_after;
  SourceMark mark;
};

struct ActionDef {
  std::string name;
  std::string description;
  uint16_t code = 0;  // written to the node's command register
  std::vector<ActionStep> steps;
  std::optional<Condition> done;
  // Written as one condition or a list: the action fails when any holds, with the error code of
  // the first that holds, in the order written. Empty: none.
  std::vector<Condition> failed;
  std::chrono::microseconds timeout{std::chrono::seconds(30)};
  bool bus_wide = false;  // affects every node on the bus (e.g. a broadcast stop)
  SourceMark mark;
};

struct PollClassDef {
  std::string name;
  std::chrono::microseconds period{0};
};

struct Model {
  std::string name;
  std::string family;
  std::string description;
  std::vector<PollClassDef> poll_classes;
  std::vector<PointDef> points;
  std::vector<SetpointDef> setpoints;
  std::vector<ActionDef> actions;
  std::map<std::string, std::string> options;  // family-specific settings, validated by the family
  std::map<std::string, SourceMark> option_marks;  // where each option was written
  std::vector<ProfileAxisDef> profile_axes;        // its axes on the axis profile, if mapped
  SourceMark mark;

  const PointDef* find_point(const std::string& point_name) const;
  const SetpointDef* find_setpoint(const std::string& setpoint_name) const;
  const ActionDef* find_action(const std::string& action_name) const;
  const ActionDef* find_action(uint16_t code) const;
  const PollClassDef* find_poll_class(const std::string& class_name) const;
  const ProfileAxisDef* find_profile_axis(const std::string& axis_name) const;
};

using ModelPtr = std::shared_ptr<const Model>;

}  // namespace fieldgate
