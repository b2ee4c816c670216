#include "gateway/config/device_writes.hpp"

namespace fieldgate {

const std::vector<DeviceWriteSpec>& device_write_specs() {
  static const std::vector<DeviceWriteSpec> specs{
      {"copley-ascii", "baud_switch",
       "'s r0x90 <baud>' to the gateway amplifier when the link opens and it answers only at "
       "its power-up rate of 9600 (serial baud other than 9600)",
       false},
      {"techno-c", "axes_definition",
       "the axes definition '@0<axes>', which clears the controller's program memory, at first "
       "contact or after a power-up (model options init_when_undefined, init_on_connect)",
       false},
      {"canopen", "heartbeat_producer",
       "SDO download of the heartbeat producer time (0x1017) to every node, when "
       "timing.heartbeat_timeout is set",
       false},
      {"canopen", "nmt_start",
       "NMT start to every node at start-up and after its boot-up (timing.start_nodes)", true},
      {"centent-cn0170", "autobaud_cr",
       "a CR for the units' auto-baud when the link opens (model option autobaud_cr)", false},
  };
  return specs;
}

std::map<std::string, bool> default_device_writes(std::string_view protocol) {
  std::map<std::string, bool> writes;
  for (const auto& s : device_write_specs())
    if (s.protocol == protocol) writes.emplace(std::string(s.name), true);
  return writes;
}

const DeviceWriteSpec* find_device_write(std::string_view protocol, std::string_view name) {
  for (const auto& s : device_write_specs())
    if (s.protocol == protocol && s.name == name) return &s;
  return nullptr;
}

std::vector<std::string> device_writes_on(std::string_view protocol,
                                          const std::map<std::string, bool>& writes) {
  std::vector<std::string> lines;
  for (const auto& [name, on] : writes)
    if (const auto* spec = find_device_write(protocol, name); on && spec)
      lines.push_back(name + ": " + std::string(spec->what));
  return lines;
}

}  // namespace fieldgate
