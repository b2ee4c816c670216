#include "gateway/console/console_port.hpp"

namespace fieldgate {

namespace {
std::optional<std::uint16_t> port_override;
}  // namespace

void set_console_port_override(std::optional<std::uint16_t> port) {
  port_override = port;
}

std::uint16_t console_port(const ConsoleConfig& config) {
  return port_override.value_or(config.port);
}

}  // namespace fieldgate
