#pragma once

#include <string>

#include "gateway/config/gateway_config.hpp"

namespace fieldgate {

// Which unit ID presents which axis on the axis profile, with the commands each supports:
// the part of the profile document that depends on the configuration.
std::string write_profile_units_document(const GatewayConfig& config);

}  // namespace fieldgate
