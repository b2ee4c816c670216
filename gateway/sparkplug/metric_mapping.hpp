#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "gateway/image/process_image.hpp"
#include "gateway/sparkplug/payload.hpp"
#include "gateway/sparkplug/sparkplug_config.hpp"
#include "mapping/model.hpp"

namespace fieldgate::sparkplug {

// The outcome of the last command a host sent to a device (DCMD), published with its metrics.
struct CommandState {
  std::string metric;     // the metric the command wrote
  std::string result;     // rejected, failed, unknown, confirmed, done, error
  std::string detail;     // why, in words
  uint64_t sequence = 0;  // counts commands, so a host can tell two equal results apart
};

// One metric of a device (a gateway node): where its value comes from in the process image.
struct DeviceMetric {
  enum class Source {
    point,      // index: model point
    point_bit,  // index: model point, bit: its bit
    setpoint,   // index: model setpoint
    action,     // index: model action; writable: true starts it
    action_status,
    action_code,
    action_error,
    diagnostic,  // index: DiagnosticField
    node_state,
    command_metric,
    command_result,
    command_detail,
    command_sequence,
  };
  std::string name;
  DataType type = DataType::int32;
  Source source = Source::point;
  int index = 0;
  int bit = 0;
  bool writable = false;
  bool slow = false;  // compared every diagnostics_interval only
  int64_t deadband = 0;
};

// Every metric of a device of this model, named after the model: points by their names (and
// "<point>/<bit>" for named bits), "Setpoints/<name>", "Actions/<name>", "Action/Status|Code|
// Error", "Diagnostics/<field>", "Command/Metric|Result|Detail|Sequence".
std::vector<DeviceMetric> device_metrics(const Model& model, const SparkplugConfig& config);

// A point's value is null (no value) until read and while stale (point_is_fresh), as on the
// register map, where it is answered 0x0B.
MetricValue sample(const DeviceMetric& metric, const Model& model, const ProcessImage& image,
                   int node_index, const CommandState& command, SteadyTime now);

// Whether `now` differs from `published` enough to be reported.
bool changed(const DeviceMetric& metric, const MetricValue& published, const MetricValue& now);

}  // namespace fieldgate::sparkplug
