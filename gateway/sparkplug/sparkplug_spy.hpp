#pragma once

#include <ostream>

#include "gateway/sparkplug/sparkplug_config.hpp"

namespace fieldgate::sparkplug {

// `fieldgate sparkplug-spy`: subscribes to the group of `config` (and to the primary hosts'
// STATE) on its broker and writes every message to `out` decoded (FleetView::take), with the
// wall-clock time, until SIGINT or SIGTERM. Publishes nothing and leaves no will. Returns the
// exit status.
int run_sparkplug_spy(const SparkplugConfig& config, std::ostream& out);

}  // namespace fieldgate::sparkplug
