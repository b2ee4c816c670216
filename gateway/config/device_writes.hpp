#pragma once

#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate {

// A write the gateway makes to a device on its own, not on a Modbus client's request:
// `writes_enabled: false` does not stop it. Each is named in a bus's `device_writes:` map and
// switched there; `fieldgate check` lists those a configuration leaves on.
struct DeviceWriteSpec {
  std::string_view protocol;
  std::string_view name;
  std::string_view what;  // the bytes or object written, and when
  // Whether the family of this build leaves the write out when switched off. A switch it does
  // not honour yet is refused (an error), never silently ignored.
  bool honoured_off;
};

const std::vector<DeviceWriteSpec>& device_write_specs();
// The writes of one protocol family, all on (their defaults).
std::map<std::string, bool> default_device_writes(std::string_view protocol);
const DeviceWriteSpec* find_device_write(std::string_view protocol, std::string_view name);
// "NAME: WHAT" for every write left on.
std::vector<std::string> device_writes_on(std::string_view protocol,
                                          const std::map<std::string, bool>& writes);

}  // namespace fieldgate
