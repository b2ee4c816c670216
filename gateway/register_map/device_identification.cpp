#include "gateway/register_map/device_identification.hpp"

#include <fmt/format.h>

#include <optional>
#include <string_view>

namespace fieldgate {

namespace {

std::string vendor_of_family(std::string_view family) {
  if (family == "copley-ascii") return "Copley Controls";
  if (family == "ims-party-line") return "Intelligent Motion Systems";
  if (family == "centent-cn0170") return "Centent Company";
  if (family == "techno-c") return "Techno-isel";
  if (family == "whedco-cmc") return "Whedco";
  return std::string(family);
}

// A point the model reads (e.g. CANopen 0x1018 identity), once a good reply has been seen.
std::optional<int64_t> read_point(const Model& model, const NodeImage& node,
                                  const std::string& name) {
  for (std::size_t i = 0; i < model.points.size() && i < node.points.size(); ++i)
    if (model.points[i].name == name && model.points[i].read && node.points[i].valid)
      return node.points[i].value;
  return std::nullopt;
}

}  // namespace

modbus::DeviceIdentification identify(const UnitMap& unit, const NodeImage& node) {
  const Model& model = *unit.model;
  std::string vendor = vendor_of_family(model.family);
  std::string product = model.name;
  std::string revision = "fieldgate " FIELDGATE_VERSION;
  if (const auto id = read_point(model, node, "vendor_id"))
    vendor = fmt::format("{} vendor ID 0x{:08X}", vendor, static_cast<uint32_t>(*id));
  if (const auto code = read_point(model, node, "product_code"))
    product = fmt::format("{} product code 0x{:08X}", product, static_cast<uint32_t>(*code));
  if (const auto rev = read_point(model, node, "revision_number"))
    revision = fmt::format("0x{:08X}", static_cast<uint32_t>(*rev));
  modbus::DeviceIdentification objects{{0x00, vendor}, {0x01, product}, {0x02, revision}};
  if (!model.description.empty()) objects.push_back({0x04, model.description});
  objects.push_back({0x05, model.name});
  objects.push_back({0x06, fmt::format("node {} on bus {}", unit.node_name, unit.bus_name)});
  return objects;
}

}  // namespace fieldgate
