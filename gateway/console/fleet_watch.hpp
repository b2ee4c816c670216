#pragma once

#include <boost/asio/any_io_executor.hpp>

#include <memory>

#include "gateway/sparkplug/fleet_view.hpp"
#include "gateway/sparkplug/session_stats.hpp"
#include "gateway/sparkplug/sparkplug_config.hpp"

namespace fieldgate {

namespace sparkplug {
class MqttConnection;
}

// The console's view of the Sparkplug fleet: a session of its own on the gateway's broker
// (client ID `<the edge node's>-console`, no will, publishing nothing) subscribed to the group
// and to the primary hosts' STATE, every message decoded into a FleetView.
class FleetWatch {
 public:
  FleetWatch(boost::asio::any_io_executor executor, const sparkplug::SparkplugConfig& config);
  ~FleetWatch();
  void start();
  void stop();
  const sparkplug::FleetView& view() const { return view_; }
  const sparkplug::SparkplugConfig& config() const { return config_; }
  bool connected() const { return stats_.connected; }

 private:
  sparkplug::SparkplugConfig config_;
  sparkplug::SessionStats stats_;
  sparkplug::FleetView view_;
  std::unique_ptr<sparkplug::MqttConnection> mqtt_;
};

}  // namespace fieldgate
