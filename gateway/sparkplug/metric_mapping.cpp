#include "gateway/sparkplug/metric_mapping.hpp"

#include <fmt/format.h>

#include "gateway/image/point_freshness.hpp"
#include "mapping/node_diagnostics.hpp"

namespace fieldgate::sparkplug {

namespace {

DataType data_type_of(ValueType type) {
  switch (type) {
    case ValueType::boolean:
      return DataType::boolean;
    case ValueType::int16:
      return DataType::int16;
    case ValueType::uint16:
      return DataType::uint16;
    case ValueType::int32:
      return DataType::int32;
    case ValueType::uint32:
      return DataType::uint32;
  }
  return DataType::int64;
}

struct DiagnosticName {
  DiagnosticField field;
  const char* name;
  DataType type;
};
// The ages (last good poll, data) are left out: they change every millisecond and a host derives
// them from the metrics' timestamps.
constexpr DiagnosticName kDiagnostics[] = {
    {DiagnosticField::online, "Diagnostics/online", DataType::boolean},
    {DiagnosticField::consecutive_timeouts, "Diagnostics/consecutive_timeouts", DataType::uint32},
    {DiagnosticField::transactions, "Diagnostics/transactions", DataType::uint32},
    {DiagnosticField::timeouts, "Diagnostics/timeouts", DataType::uint32},
    {DiagnosticField::errors, "Diagnostics/errors", DataType::uint32},
    {DiagnosticField::last_device_error, "Diagnostics/last_device_error", DataType::uint16},
    {DiagnosticField::unknown_writes, "Diagnostics/unknown_writes", DataType::uint32},
};

std::string_view action_status_text(ActionStatus s) {
  switch (s) {
    case ActionStatus::idle:
      return "idle";
    case ActionStatus::busy:
      return "busy";
    case ActionStatus::done:
      return "done";
    case ActionStatus::error:
      return "error";
  }
  return "?";
}

}  // namespace

std::vector<DeviceMetric> device_metrics(const Model& model, const SparkplugConfig& config) {
  using S = DeviceMetric::Source;
  std::vector<DeviceMetric> out;
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    const auto& p = model.points[i];
    const int index = static_cast<int>(i);
    out.push_back({p.name, data_type_of(p.type), S::point, index, 0, p.writable(), false,
                   config.deadband(p.type)});
    for (const auto& b : p.bits)
      out.push_back({fmt::format("{}/{}", p.name, b.name), DataType::boolean, S::point_bit, index,
                     b.bit, false, false, 0});
  }
  for (std::size_t i = 0; i < model.setpoints.size(); ++i) {
    const auto& s = model.setpoints[i];
    out.push_back({"Setpoints/" + s.name, data_type_of(s.type), S::setpoint, static_cast<int>(i), 0,
                   true, false, config.deadband(s.type)});
  }
  for (std::size_t i = 0; i < model.actions.size(); ++i)
    out.push_back({"Actions/" + model.actions[i].name, DataType::boolean, S::action,
                   static_cast<int>(i), 0, true, false, 0});
  out.push_back({"Action/Status", DataType::string, S::action_status, 0, 0, false, false, 0});
  out.push_back({"Action/Code", DataType::uint16, S::action_code, 0, 0, false, false, 0});
  out.push_back({"Action/Error", DataType::uint16, S::action_error, 0, 0, false, false, 0});
  out.push_back({"Diagnostics/node_state", DataType::string, S::node_state, 0, 0, false, false, 0});
  for (const auto& d : kDiagnostics)
    out.push_back({d.name, d.type, S::diagnostic, static_cast<int>(d.field), 0, false,
                   d.field != DiagnosticField::online, 0});
  out.push_back({"Command/Metric", DataType::string, S::command_metric, 0, 0, false, false, 0});
  out.push_back({"Command/Result", DataType::string, S::command_result, 0, 0, false, false, 0});
  out.push_back({"Command/Detail", DataType::string, S::command_detail, 0, 0, false, false, 0});
  out.push_back({"Command/Sequence", DataType::uint64, S::command_sequence, 0, 0, false, false, 0});
  // The PLCopen axis profile (issue #14) adds its metrics here, as "Profile/<name>" with a
  // source reading the profile's view of the node; everything else (births, report by
  // exception, DCMD through the control service) then applies to them unchanged.
  return out;
}

MetricValue sample(const DeviceMetric& m, const Model& model, const ProcessImage& image,
                   int node_index, const CommandState& command, SteadyTime now) {
  using S = DeviceMetric::Source;
  const NodeImage& node = image.node(node_index);
  MetricValue v;
  switch (m.source) {
    case S::point:
    case S::point_bit: {
      const auto& pv = node.points.at(static_cast<std::size_t>(m.index));
      if (!point_is_fresh(node, model, static_cast<std::size_t>(m.index), now)) {
        v.is_null = true;
      } else {
        v.number = m.source == S::point ? pv.value : ((pv.value >> m.bit) & 1);
      }
      break;
    }
    case S::setpoint:
      v.number = node.setpoints.at(static_cast<std::size_t>(m.index));
      break;
    case S::action:
      v.number = 0;  // a trigger: reads false, true starts the action
      break;
    case S::action_status:
      v.text = std::string(action_status_text(node.action.status));
      break;
    case S::action_code:
      v.number = node.action.code;
      break;
    case S::action_error:
      v.number = node.action.error;
      break;
    case S::diagnostic:
      v.number = image.diagnostic(node_index, static_cast<DiagnosticField>(m.index), now);
      break;
    case S::node_state:
      v.text = std::string(to_string(node.state));
      break;
    case S::command_metric:
      v.text = command.metric;
      break;
    case S::command_result:
      v.text = command.result;
      break;
    case S::command_detail:
      v.text = command.detail;
      break;
    case S::command_sequence:
      v.number = static_cast<int64_t>(command.sequence);
      break;
  }
  return v;
}

bool changed(const DeviceMetric& m, const MetricValue& published, const MetricValue& now) {
  if (published.is_null != now.is_null) return true;
  if (now.is_null) return false;
  if (m.type == DataType::string) return published.text != now.text;
  const int64_t delta =
      now.number > published.number ? now.number - published.number : published.number - now.number;
  return delta > m.deadband;
}

}  // namespace fieldgate::sparkplug
