#include "gateway/sparkplug/sparkplug_spy.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <unistd.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>

#include <csignal>

#include "gateway/sparkplug/fleet_view.hpp"
#include "gateway/sparkplug/mqtt_connection.hpp"
#include "gateway/sparkplug/payload.hpp"
#include "gateway/sparkplug/session_stats.hpp"

namespace fieldgate::sparkplug {

int run_sparkplug_spy(const SparkplugConfig& given, std::ostream& out) {
  SparkplugConfig config = given;
  // Its own client ID: the edge node's would take over the gateway's session.
  config.client_id = fmt::format("fieldgate-spy-{}-{}", config.group_id, ::getpid());
  asio::io_context io;
  SessionStats stats;
  FleetView view;
  std::unique_ptr<MqttConnection> mqtt;
  MqttConnection::Handlers handlers;
  handlers.connected = [&] {
    out << fmt::format("connected to {}:{}; group {}\n", config.host, config.port, config.group_id)
        << std::flush;
    mqtt->subscribe(fmt::format("spBv1.0/{}/#", config.group_id), 1);
    mqtt->subscribe("spBv1.0/STATE/#", 1);
  };
  handlers.disconnected = [&] { out << "disconnected; reconnecting\n" << std::flush; };
  handlers.message = [&](const std::string& topic, std::string_view payload) {
    const auto now = std::chrono::system_clock::now();
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch());
    out << fmt::format("{:%F %T}.{:03d} ", std::chrono::floor<std::chrono::seconds>(now),
                       static_cast<int>(ms.count() % 1000))
        << view.take(topic, payload, static_cast<uint64_t>(ms.count())) << std::flush;
  };
  mqtt = std::make_unique<MqttConnection>(io.get_executor(), config, std::move(handlers), stats);
  asio::signal_set signals(io, SIGINT, SIGTERM);
  signals.async_wait([&](const boost::system::error_code&, int) {
    mqtt->stop();
    io.stop();
  });
  mqtt->start();
  io.run();
  return 0;
}

}  // namespace fieldgate::sparkplug
