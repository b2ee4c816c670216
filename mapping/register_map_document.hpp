#pragma once

#include <string>
#include <vector>

#include "mapping/register_map.hpp"

namespace fieldgate {

enum class DocumentFormat { markdown, csv };

// The register map for the PLC programmer, written from the same RegisterMap the Modbus server
// serves: per unit every table and address (0-based and in 3xxxx/4xxxx notation), name, type,
// word order, units and scale, access, and the action codes.
std::string write_register_map_document(const RegisterMap& map, DocumentFormat format);

// One Modbus endpoint's unit-ID space, for a gateway with several.
struct ListenerMap {
  std::string name;
  std::string endpoint;  // ADDRESS:PORT
  const RegisterMap* map = nullptr;
};

// Every listener's table, each under its name and endpoint (CSV: a leading listener column).
// With a single listener the document is the one above.
std::string write_register_map_document(const std::vector<ListenerMap>& listeners,
                                        DocumentFormat format);

// Modicon reference of a 0-based address: 1xxxx discrete inputs, 3xxxx input registers,
// 4xxxx holding registers, 0xxxx coils; six digits where five do not fit.
std::string modicon_reference(Table table, uint16_t address);

}  // namespace fieldgate
