#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "mapping/diagnostics.hpp"
#include "mapping/model.hpp"
#include "mapping/node_diagnostics.hpp"
#include "mapping/value_type.hpp"

namespace fieldgate {

enum class Table { coils = 0, discrete_inputs = 1, input_registers = 2, holding_registers = 3 };
std::string_view to_string(Table table);

// Fixed places every node's map shares, so a PLC programmer learns them once.
namespace layout {
inline constexpr uint16_t action_block = 100;  // holding: command, status, error, sequence
inline constexpr uint16_t setpoints = 110;     // holding: action parameters
inline constexpr uint16_t diagnostics = 1000;  // input registers
inline constexpr uint16_t online_bit = 1000;   // discrete input
}  // namespace layout

struct RegisterEntry {
  enum class Kind {
    point,           // index = point index in the model
    point_bit,       // index = point index, bit = bit number
    setpoint,        // index = setpoint index
    action_command,  // write: run the action with this code
    action_status,
    action_error,
    action_sequence,  // counts accepted commands, so a PLC sees its command was taken
    diagnostic,       // index = DiagnosticField
  };
  Kind kind = Kind::point;
  uint16_t address = 0;
  uint16_t count = 1;  // registers, or 1 for a bit
  ValueType type = ValueType::uint16;
  int index = 0;
  int bit = 0;
  bool writable = false;
  std::string name;
  std::string units;
  double scale = 1.0;
  std::string description;
};

struct UnitMap {
  uint8_t unit_id = 0;
  int node_index = 0;  // the gateway's global node number
  std::string node_name;
  std::string bus_name;
  ModelPtr model;
  std::array<std::vector<RegisterEntry>, 4> tables;  // each sorted by address

  // The entry covering address, or nullptr.
  const RegisterEntry* find(Table table, uint16_t address) const;
};

struct NodeBinding {
  uint8_t unit_id = 0;
  int node_index = 0;
  std::string node_name;
  std::string bus_name;
  ModelPtr model;
};

class RegisterMap {
 public:
  // Lays out every node's map from its model. Fails (with diagnostics at the model's marks)
  // when a model's writable points or setpoints do not fit their fixed areas.
  static RegisterMap build(const std::vector<NodeBinding>& nodes, WordOrder order,
                           Diagnostics& diagnostics);

  const UnitMap* unit(uint8_t unit_id) const;
  const std::map<uint8_t, UnitMap>& units() const { return units_; }
  WordOrder word_order() const { return word_order_; }

 private:
  std::map<uint8_t, UnitMap> units_;
  WordOrder word_order_ = WordOrder::high_first;
};

}  // namespace fieldgate
