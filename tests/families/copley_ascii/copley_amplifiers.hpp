#pragma once

// The line most Copley end-to-end tests run against: the simulator's amplifiers at addresses 0,
// 3 and 5, configured as the daemon's units 1, 2 and 3.

#include <memory>
#include <string>

#include "harness.hpp"

namespace fieldgate::test {

// The simulator's --nodes.
inline constexpr const char* kAmplifierAddresses = "0,3,5";
// The bus's nodes in the daemon's configuration.
inline constexpr const char* kAmplifierNodes =
    "      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1}\n"
    "      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2}\n"
    "      - {name: amp5, address: 5, model: copley-amplifier, unit_id: 3}\n";

// A CopleyPlant with the three amplifiers; extra_nodes are configured after them.
inline std::unique_ptr<CopleyPlant> amplifier_plant(const std::string& extra_nodes = "") {
  return std::make_unique<CopleyPlant>(kAmplifierAddresses, kAmplifierNodes + extra_nodes);
}

}  // namespace fieldgate::test
