#include "drivers/canopen/node_points.hpp"

#include <fmt/format.h>

namespace fieldgate::canopen {

Request poll_request(const PollJob& job) {
  return Request{job.kind == PollJob::Kind::local
                     ? std::string("local")
                     : "read " + fmt::format("0x{:04X}:{} {}", job.object.index, job.object.sub,
                                             to_string(job.object.type)),
                 Request::Expect::values};
}

NodePoints::NodePoints(uint8_t node, const Model& model, const OnError& on_error) : node_(node) {
  types_.reserve(model.points.size());
  for (const auto& point : model.points) types_.push_back(point.type);
  sources_.resize(model.points.size());
  for (std::size_t p = 0; p < model.points.size(); ++p) {
    const auto& point = model.points[p];
    if (!point.read) continue;
    std::string error;
    auto src = compile_point_read(point, error);
    if (!src) {
      on_error(point, error);
      continue;
    }
    sources_[p] = src;
    const int pi = static_cast<int>(p);
    if (src->kind == PointSource::Kind::local) local_points_.push_back(pi);
    if (src->kind == PointSource::Kind::tpdo) tpdo_points_[src->tpdo.cob_for(node_)].push_back(pi);
  }
}

std::optional<PollJob> NodePoints::poll_job(std::size_t point) const {
  const auto& src = sources_.at(point);
  if (!src) return std::nullopt;
  PollJob job;
  switch (src->kind) {
    case PointSource::Kind::local:
      job.kind = PollJob::Kind::local;
      break;
    case PointSource::Kind::tpdo:
      if (!src->object) return std::nullopt;  // nothing to fall back on
      job.kind = PollJob::Kind::tpdo_fallback;
      job.object = *src->object;
      job.tpdo_cob = src->tpdo.cob_for(node_);
      break;
    case PointSource::Kind::sdo:
      job.kind = PollJob::Kind::sdo;
      job.object = *src->object;
      break;
  }
  return job;
}

std::vector<uint32_t> NodePoints::tpdo_cobs() const {
  std::vector<uint32_t> cobs;
  for (const auto& [cob, points] : tpdo_points_) cobs.push_back(cob);
  return cobs;
}

std::vector<int> NodePoints::nmt_state_points() const {
  std::vector<int> points;
  for (const int p : local_points_)
    if (sources_[static_cast<std::size_t>(p)]->local == LocalValue::nmt_state) points.push_back(p);
  return points;
}

std::vector<PointUpdate> NodePoints::from_tpdo(const CanFrame& frame,
                                               std::vector<std::string>& errors) const {
  std::vector<PointUpdate> updates;
  const auto it = tpdo_points_.find(frame.id);
  if (it == tpdo_points_.end()) return updates;
  for (const int p : it->second) {
    std::string error;
    const auto v = decode_tpdo_value(*sources_[static_cast<std::size_t>(p)], frame, error);
    if (!v) {
      errors.push_back(std::move(error));
      continue;
    }
    updates.push_back({p, *v});
  }
  return updates;
}

std::vector<PointUpdate> NodePoints::from_object(uint16_t index, uint8_t sub,
                                                 std::span<const uint8_t> bytes) const {
  std::vector<PointUpdate> updates;
  for (std::size_t p = 0; p < sources_.size(); ++p) {
    const auto& src = sources_[p];
    if (!src || src->kind == PointSource::Kind::local || !src->object ||
        src->object->index != index || src->object->sub != sub)
      continue;
    std::string error;
    const auto v = decode_point_value(*src, types_[p], bytes, error);
    if (!v) continue;
    updates.push_back({static_cast<int>(p), *v});
  }
  return updates;
}

std::vector<PointUpdate> NodePoints::absent_values(uint16_t index, uint8_t sub) const {
  std::vector<PointUpdate> updates;
  for (std::size_t p = 0; p < sources_.size(); ++p) {
    const auto& src = sources_[p];
    if (src && src->kind == PointSource::Kind::sdo && src->object && src->object->index == index &&
        src->object->sub == sub)
      updates.push_back({static_cast<int>(p), 0});
  }
  return updates;
}

std::vector<PointUpdate> NodePoints::local_values(const NodeStatus& status) const {
  std::vector<PointUpdate> updates;
  for (const int p : local_points_) {
    int64_t v = 0;
    switch (sources_[static_cast<std::size_t>(p)]->local) {
      case LocalValue::emcy_code:
        v = status.emcy_code;
        break;
      case LocalValue::emcy_register:
        v = status.emcy_register;
        break;
      case LocalValue::nmt_state:
        if (!status.nmt_state) continue;  // no heartbeat seen yet: no value
        v = *status.nmt_state;
        break;
      case LocalValue::sdo_abort:
        v = status.last_abort;
        break;
    }
    updates.push_back({p, v});
  }
  return updates;
}

}  // namespace fieldgate::canopen
