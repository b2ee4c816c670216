// The objects a node turned out not to have: a poll answered with abort 0x06020000 (object does
// not exist) or 0x06090011 (sub-index does not exist). CiA 301 makes many objects optional
// (0x1008 device name, 0x1009, 0x100A, ...), and a shipped model may poll one the device lacks:
// such an object is polled no more and its points read as the object's empty value, so it
// neither makes its neighbours unreadable nor overwrites the abort diagnostics of a command.
#pragma once

#include <cstdint>
#include <set>
#include <utility>

#include "drivers/canopen/canopen_codec.hpp"

namespace fieldgate::canopen {

// Does the abort say the object (or its sub-index) is not in the device's dictionary?
constexpr bool says_absent(uint32_t abort_code) {
  return abort_code == sdo_abort::no_object || abort_code == sdo_abort::no_subindex;
}

class AbsentObjects {
 public:
  bool contains(uint16_t index, uint8_t sub) const { return objects_.count({index, sub}) > 0; }
  // True the first time the object is found absent.
  bool add(uint16_t index, uint8_t sub) { return objects_.insert({index, sub}).second; }
  bool empty() const { return objects_.empty(); }
  // The node restarted (boot-up): it may be another device or firmware now.
  void clear() { objects_.clear(); }

 private:
  std::set<std::pair<uint16_t, uint8_t>> objects_;
};

}  // namespace fieldgate::canopen
