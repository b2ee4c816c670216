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
  return NodeAddress{std::to_string(*id), *id, 0};
}

void CanopenFamily::validate_model(const Model& model, Diagnostics& diagnostics) const {
  check_model_options(model, name(), model_options(), diagnostics);
  const auto zero = [](std::string_view) { return int64_t{0}; };
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
    const auto op = parse_operation(p.write->request.render(zero), &model, error);
    if (!op) {
      diagnostics.error(p.mark, fmt::format("{} write: {}", where, error));
      continue;
    }
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
      const auto op = parse_operation(s.command.render(zero), &model, error);
      if (!op) {
        diagnostics.error(s.mark,
                          fmt::format("{}: step '{}': {}", where, s.command.source(), error));
        continue;
      }
      if (a.bus_wide && op->kind != Operation::Kind::nmt)
        diagnostics.error(s.mark, fmt::format("{}: step '{}': a bus-wide action may only send "
                                              "NMT commands (SDO has no broadcast)",
                                              where, s.command.source()));
    }
  }
}

asio::awaitable<Reply> CanopenFamily::transact(Link&, const NodeAddress&, const Request& request,
                                               const LinkTiming&) {
  Reply r;
  r.status = Reply::Status::link_down;
  r.text = fmt::format("'{}': the canopen family runs on a CAN bus (can: {{interface: ...}})",
                       request.command);
  co_return r;
}

std::size_t CanopenFamily::estimate_wire_chars(const NodeAddress&, const Request&) const {
  return 0;  // CAN frames are not characters on a serial line; the serial budget does not apply
}

FamilyPtr make_canopen_family() {
  return std::make_shared<CanopenFamily>();
}

}  // namespace fieldgate
