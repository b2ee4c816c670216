#include "drivers/canopen/canopen_family.hpp"

#include <fmt/format.h>

#include "drivers/canopen/canopen_codec.hpp"
#include "drivers/canopen/canopen_request.hpp"

namespace fieldgate {

using namespace canopen;

std::optional<NodeAddress> CanopenFamily::parse_address(std::string_view text,
                                                        std::string& error) const {
  const auto id = parse_node_id(text, error);
  if (!id) return std::nullopt;
  return NodeAddress::numbered(*id);
}

void CanopenFamily::validate_model(const Model& model, Diagnostics& diagnostics) const {
  check_model_options(model, name(), model_options(), diagnostics);
  for (const auto& p : model.points) {
    const std::string where = fmt::format("model {}: point {}", model.name, p.name);
    if (p.read) {
      std::string error;
      if (!compile_point_read(p, error))
        diagnostics.error(p.mark, fmt::format("{} read: {}", where, error));
    }
    if (!p.write) continue;
    if (p.write->request.empty()) {
      const std::string object =
          p.write->object
              ? fmt::format("0x{:04X}:{}", p.write->object->index, p.write->object->subindex)
              : std::string("INDEX:SUB");
      diagnostics.error(p.mark, fmt::format("{} write: a canopen point write is request text the "
                                            "bus runs, e.g. write: \"write {} {{value}}\"",
                                            where, object));
      continue;
    }
    std::string error;
    const auto compiled = compile_operation(p.write->request, &model, error);
    if (!compiled) {
      diagnostics.error(p.mark, fmt::format("{} write: {}", where, error));
      continue;
    }
    const Operation* op = &compiled->operation();
    if (op->kind != Operation::Kind::write || !is_integer(op->object.type)) {
      diagnostics.error(p.mark, fmt::format("{} write: expected 'write OBJECT {{value}}' with an "
                                            "integer object, found '{}'",
                                            where, p.write->request.source()));
      continue;
    }
    if (p.write->object) {
      const ObjectAddress declared{
          p.write->object->index, p.write->object->subindex,
          parse_data_type(p.write->object->data_type).value_or(op->object.type)};
      if (!(declared == op->object))
        diagnostics.error(p.mark, fmt::format("{} write: the object is {} but the request writes "
                                              "{}",
                                              where, to_string(declared), to_string(op->object)));
    }
    // The register map refuses values outside the point's min/max with 0x03 before anything is
    // sent, so those limits must keep values inside the data type.
    const int64_t lo = p.min.value_or(min_value(p.type));
    const int64_t hi = p.max.value_or(max_value(p.type));
    if (lo < min_of(op->object.type) || hi > max_of(op->object.type))
      diagnostics.error(p.mark, fmt::format("{}: values {}..{} reach outside {} ({}..{}); set "
                                            "min and max",
                                            where, lo, hi, to_string(op->object.type),
                                            min_of(op->object.type), max_of(op->object.type)));
  }
  for (const auto& a : model.actions) {
    for (const auto& s : a.steps) {
      if (s.kind != ActionStep::Kind::send) continue;
      const std::string where = fmt::format("model {}: action {}", model.name, a.name);
      std::string error;
      const auto compiled = compile_operation(s.command, &model, error);
      if (!compiled) {
        diagnostics.error(s.mark,
                          fmt::format("{}: step '{}': {}", where, s.command.source(), error));
        continue;
      }
      if (a.bus_wide && compiled->operation().kind != Operation::Kind::nmt)
        diagnostics.error(s.mark, fmt::format("{}: step '{}': a bus-wide action may only send "
                                              "NMT commands (SDO has no broadcast)",
                                              where, s.command.source()));
    }
  }
}

void CanopenFamily::compile_commands(Model& model) const {
  std::string error;  // validate_model reported it; a model with errors never runs
  for (auto& p : model.points)
    if (p.write && !p.write->request.empty())
      p.write->request.set_compiled(compile_operation(p.write->request, &model, error));
  for (auto& a : model.actions)
    for (auto& s : a.steps)
      if (s.kind == ActionStep::Kind::send)
        s.command.set_compiled(compile_operation(s.command, &model, error));
}

std::vector<uint32_t> CanopenFamily::receive_ids(const NodeAddress& node,
                                                 const Model& model) const {
  const auto id = static_cast<uint8_t>(node.number);
  std::vector<uint32_t> ids{cob::sdo_tx + id, cob::heartbeat + id, cob::emcy + id};
  for (const auto& point : model.points) {
    if (!point.read) continue;
    std::string error;
    const auto src = compile_point_read(point, error);
    if (src && src->kind == PointSource::Kind::tpdo) ids.push_back(src->tpdo.cob_for(id));
  }
  return ids;
}

FrameRole CanopenFamily::classify(const NodeAddress& node, const CanFrame& frame) const {
  const auto id = static_cast<uint32_t>(node.number);
  if (frame.error || frame.rtr) return FrameRole::none;
  if (frame.id == cob::sdo_tx + id) return FrameRole::transfer_response;
  if (frame.id == cob::heartbeat + id) return FrameRole::heartbeat;
  if (frame.id == cob::emcy + id) return FrameRole::emergency;
  return FrameRole::other;
}

int CanopenFamily::frame_node(const CanFrame& frame) const {
  if (frame.error) return kNoNode;
  // NMT names its node in the data (0: every node); every other COB-ID in its low seven bits.
  if (frame.id == cob::nmt) {
    const int node = frame.len > 1 ? frame.data[1] : 0;
    return node == 0 ? kEveryNode : node;
  }
  return static_cast<int>(frame.id & 0x7f);
}

FamilyPtr make_canopen_family() {
  return std::make_shared<CanopenFamily>();
}

}  // namespace fieldgate
