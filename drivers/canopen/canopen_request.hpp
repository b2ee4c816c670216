// The canopen family's request grammar (action steps, point writes, point read sources) and
// the decoding of point values. Pure: compiled against a model when the configuration loads;
// at run time a command only has its placeholders' values filled in (CompiledOperation).
//
//   read OBJECT                              SDO upload
//   write OBJECT VALUE                       SDO download; VALUE is an integer or "a string"
//   wait OBJECT [& MASK] == VALUE [within D] SDO uploads until (value & MASK) == VALUE
//   nmt start|stop|pre-operational|reset|reset-communication
//
// OBJECT is INDEX:SUB with an optional data type (0x6040:0 UNSIGNED16), or a point name of the
// model, which stands for the point's object. Without a type, the model must declare that
// index:subindex on some point.
//
// Point read sources (the point's `read:`):
//   {object: "0x6064:0", data_type: INTEGER32}                 polled by SDO upload
//   {object: ..., data_type: ..., request: "tpdo 0x180+id byte 2"}
//                                  taken from a TPDO; SDO only when the PDO is older than the
//                                  point's poll period
//   request: "emcy code" | "emcy register" | "nmt state" | "sdo abort"
//                                  what the gateway consumed from the node: last emergency code
//                                  and error register, NMT state from its heartbeat, last SDO
//                                  abort code
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/canopen/canopen_codec.hpp"
#include "drivers/canopen/canopen_time.hpp"
#include "drivers/transport/can_frame.hpp"
#include "mapping/model.hpp"

namespace fieldgate::canopen {

struct ObjectAddress {
  uint16_t index = 0;
  uint8_t sub = 0;
  DataType type = DataType::unsigned8;

  friend bool operator==(const ObjectAddress&, const ObjectAddress&) = default;
};
std::string to_string(const ObjectAddress& object);  // "0x6040:0 UNSIGNED16"

struct Operation {
  enum class Kind { read, write, wait, nmt };
  Kind kind = Kind::read;
  ObjectAddress object;
  int64_t value = 0;                // write (integer types), wait (expected value)
  std::optional<std::string> text;  // write of a string type
  uint64_t mask = ~uint64_t{0};     // wait
  std::chrono::microseconds within{std::chrono::seconds(2)};  // wait
  NmtCommand nmt = NmtCommand::start;
};

// Parses one rendered request. model (may be null) resolves point names and data types.
std::optional<Operation> parse_operation(std::string_view text, const Model* model,
                                         std::string& error);

// A command template parsed once: the operation, and the field each placeholder fills (a
// write's value, a wait's value or mask). Running it fills in the values, parsing nothing.
class CompiledOperation : public CompiledCommand {
 public:
  enum class Slot { value, mask };

  CompiledOperation(Operation operation, std::vector<Slot> slots)
      : operation_(std::move(operation)), slots_(std::move(slots)) {}

  // The operation with `arguments` (one per placeholder, in template order) in their fields;
  // nullopt with error when their number is wrong or a written value does not fit its object.
  std::optional<Operation> with(std::span<const int64_t> arguments, std::string& error) const;
  const Operation& operation() const { return operation_; }

 private:
  Operation operation_;
  std::vector<Slot> slots_;
};

// Compiles a template of `model` (may be null). A placeholder must stand for a whole integer
// the operation takes as its value (or a wait's mask): anywhere else it is an error, at load.
std::shared_ptr<const CompiledOperation> compile_operation(const CommandTemplate& command,
                                                           const Model* model, std::string& error);

enum class LocalValue { emcy_code, emcy_register, nmt_state, sdo_abort };

struct TpdoSlot {
  uint32_t cob_id = 0;    // or the base, when per_node
  bool per_node = false;  // "0x180+id"
  uint8_t offset = 0;     // first byte of the value in the PDO

  uint32_t cob_for(uint8_t node) const { return per_node ? cob_id + node : cob_id; }
  friend bool operator==(const TpdoSlot&, const TpdoSlot&) = default;
};

struct PointSource {
  enum class Kind { sdo, tpdo, local };
  Kind kind = Kind::sdo;
  std::optional<ObjectAddress> object;  // sdo; tpdo (SDO fallback, when given)
  DataType type = DataType::unsigned8;  // of the value (tpdo without object included)
  TpdoSlot tpdo;
  LocalValue local = LocalValue::emcy_code;
  int field = 0;  // string objects: which chunk of the text
};

// The source of a point's value, checked against the point's type.
std::optional<PointSource> compile_point_read(const PointDef& point, std::string& error);

// The point's value from uploaded bytes: the integer, or for a string object chunk `field` of
// the text with its first character in the most significant byte (2 characters for a 16-bit
// point, 4 for a 32-bit one), so a PLC reading the registers high word first sees the text.
std::optional<int64_t> decode_point_value(const PointSource& source, ValueType type,
                                          std::span<const uint8_t> bytes, std::string& error);
// The point's value from a PDO, or nullopt (with error) when the PDO is too short.
std::optional<int64_t> decode_tpdo_value(const PointSource& source, const CanFrame& frame,
                                         std::string& error);

}  // namespace fieldgate::canopen
