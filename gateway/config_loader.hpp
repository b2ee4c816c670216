#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gateway/gateway_config.hpp"
#include "mapping/register_map.hpp"

namespace fieldgate {

struct LoadedConfig {
  GatewayConfig gateway;
  RegisterMap register_map;
};

// Reads and checks a whole gateway configuration, its models included, without opening any
// port. On failure every problem found is in diagnostics and nullopt is returned.
std::optional<LoadedConfig> load_gateway_config(const std::string& path, Diagnostics& diagnostics);

}  // namespace fieldgate
