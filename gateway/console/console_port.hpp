#pragma once

#include <cstdint>
#include <optional>

#include "gateway/config/gateway_config.hpp"

namespace fieldgate {

// The console's port from the command line or the environment (`fieldgate --console-port`,
// FIELDGATE_CONSOLE_PORT; the command line first): it takes the place of the port of the
// configuration's `console: listen:`, at start and at every reload (docs/console.md). Set once,
// before the daemon starts; nullopt: the configuration's port.
void set_console_port_override(std::optional<std::uint16_t> port);

// The port the console listens on: the override, else the configuration's.
std::uint16_t console_port(const ConsoleConfig& config);

}  // namespace fieldgate
