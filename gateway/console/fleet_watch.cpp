#include "gateway/console/fleet_watch.hpp"

#include <fmt/format.h>

#include "gateway/sparkplug/mqtt_connection.hpp"
#include "gateway/sparkplug/payload.hpp"

namespace fieldgate {

FleetWatch::FleetWatch(boost::asio::any_io_executor executor,
                       const sparkplug::SparkplugConfig& config)
    : config_(config) {
  // Its own client ID: the edge node's own would end the gateway's session.
  config_.client_id = config.effective_client_id() + "-console";
  sparkplug::MqttConnection::Handlers handlers;
  handlers.connected = [this] {
    mqtt_->subscribe(fmt::format("spBv1.0/{}/#", config_.group_id), 1);
    mqtt_->subscribe("spBv1.0/STATE/#", 1);
  };
  handlers.message = [this](const std::string& topic, std::string_view payload) {
    view_.take(topic, payload, sparkplug::now_ms());
  };
  mqtt_ =
      std::make_unique<sparkplug::MqttConnection>(executor, config_, std::move(handlers), stats_);
}

FleetWatch::~FleetWatch() = default;

void FleetWatch::start() {
  mqtt_->start();
}

void FleetWatch::stop() {
  mqtt_->stop();
}

}  // namespace fieldgate
