#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/awaitable.hpp>

#include <functional>
#include <memory>
#include <string>

#include "gateway/config/config_loader.hpp"
#include "gateway/control/control_service.hpp"
#include "gateway/image/process_image.hpp"
#include "gateway/sparkplug/metric_mapping.hpp"
#include "gateway/sparkplug/payload.hpp"

namespace fieldgate::sparkplug {

// The device a command is for, in the configuration generation it arrived in.
struct CommandTarget {
  std::shared_ptr<const LoadedConfig> config;
  std::shared_ptr<ControlService> control;
  ProcessImage* image = nullptr;
  int node_index = 0;
  WritePolicy policy;
};

struct CommandOutcome {
  std::string result;  // rejected, failed, unknown, confirmed, done, error, superseded
  std::string detail;
  bool final = false;
};

using CommandReport = std::function<void(const CommandOutcome&)>;

// Carries out one DCMD metric through the control service, under the same rules as every other
// door's write (limits, the node's write policy, a held line, confirmation by the controller,
// the action runner). A written action is then followed to its end (done, error) or, when no
// end is seen within its timeout, reported 'unknown'.
asio::awaitable<void> execute_command(CommandTarget target, DeviceMetric metric, Metric value,
                                      CommandReport report);

}  // namespace fieldgate::sparkplug
