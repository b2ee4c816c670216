#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gateway/config/gateway_config.hpp"
#include "mapping/register_map.hpp"

namespace fieldgate {

struct LoadedConfig {
  GatewayConfig gateway;
  RegisterMap register_map;                // the default listener's (`modbus:`)
  std::vector<RegisterMap> listener_maps;  // one per gateway.listeners entry, in order

  // The unit-ID space of a listener (index as in GatewayConfig::listener_modbus).
  const RegisterMap& map_of(std::size_t listener) const {
    return listener == 0 ? register_map : listener_maps.at(listener - 1);
  }
};

// Reads and checks a whole gateway configuration, its models included, without opening any
// port. On failure every problem found is in diagnostics and nullopt is returned.
std::optional<LoadedConfig> load_gateway_config(const std::string& path, Diagnostics& diagnostics);

}  // namespace fieldgate
