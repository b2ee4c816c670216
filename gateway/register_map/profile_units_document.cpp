#include "gateway/register_map/profile_units_document.hpp"

#include <fmt/format.h>

#include <map>

namespace fieldgate {

std::string write_profile_units_document(const GatewayConfig& config) {
  struct Row {
    std::string node, bus, axis, model, supported, unsupported;
  };
  std::map<int, Row> rows;
  for (const auto& bus : config.buses)
    for (const auto& node : bus.nodes)
      for (const auto& [axis_name, unit] : node.axis_units) {
        const auto* axis = node.model->find_profile_axis(axis_name);
        if (!axis) continue;
        Row r{node.name, bus.name, axis_name, node.model->name, "", ""};
        for (uint16_t c = 1; c < kProfileCommandCount; ++c) {
          auto& list = axis->supports(static_cast<ProfileCommand>(c)) ? r.supported : r.unsupported;
          list += fmt::format("{}{}", list.empty() ? "" : ", ",
                              to_string(static_cast<ProfileCommand>(c)));
        }
        rows[unit] = std::move(r);
      }
  std::string out = "\n## Profile units of this configuration\n\n";
  if (rows.empty()) return out + "None: no node has `profile_unit` or `axis_units`.\n";
  out +=
      "| unit | node | bus | axis | model | supported | unsupported (exception 0x01) |\n"
      "|---|---|---|---|---|---|---|\n";
  for (const auto& [unit, r] : rows)
    out += fmt::format("| {} | {} | {} | {} | {} | {} | {} |\n", unit, r.node, r.bus, r.axis,
                       r.model, r.supported, r.unsupported.empty() ? "-" : r.unsupported);
  return out;
}

}  // namespace fieldgate
