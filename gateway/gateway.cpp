#include "gateway/gateway.hpp"

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/ip/address.hpp>

#include "gateway/log.hpp"

namespace fieldgate {

namespace {
std::size_t count_nodes(const GatewayConfig& g) {
  std::size_t n = 0;
  for (const auto& b : g.buses) n += b.nodes.size();
  return n;
}
}  // namespace

Gateway::Gateway(asio::io_context& io, std::shared_ptr<const LoadedConfig> config)
    : io_(io),
      config_(std::move(config)),
      image_(count_nodes(config_->gateway)),
      actions_(io.get_executor(), image_, [this](int n) -> Bus& { return bus_of(n); }) {
  int first = 0;
  for (const auto& bus : config_->gateway.buses) {
    buses_.push_back(make_bus(io.get_executor(), bus, first, image_,
                              [this](int n) { actions_.node_updated(n); }));
    for (std::size_t i = 0; i < bus.nodes.size(); ++i)
      bus_of_node_.push_back(static_cast<int>(buses_.size() - 1));
    first += static_cast<int>(bus.nodes.size());
  }
  handler_ = std::make_shared<RegisterMapHandler>(config_, image_, actions_,
                                                  [this](int n) -> Bus& { return bus_of(n); });
}

Gateway::~Gateway() {
  stop();
}

Bus& Gateway::bus_of(int node_index) {
  return *buses_.at(
      static_cast<std::size_t>(bus_of_node_.at(static_cast<std::size_t>(node_index))));
}

void Gateway::start() {
  const auto& m = config_->gateway.modbus;
  modbus::ModbusTcpServerOptions options;
  options.endpoint = asio::ip::tcp::endpoint(asio::ip::make_address(m.address), m.port);
  options.max_clients = m.max_clients;
  options.idle_timeout = m.idle_timeout;
  server_ = std::make_unique<modbus::ModbusTcpServer>(io_.get_executor(), options, handler_);
  server_->start();
  log::notice("modbus: listening on {}", server_->local_endpoint().address().to_string() + ":" +
                                             std::to_string(server_->local_endpoint().port()));
  for (auto& bus : buses_) asio::co_spawn(io_, bus->run(), asio::detached);
}

void Gateway::stop() {
  if (server_) server_->stop();
  for (auto& bus : buses_) bus->stop();
  actions_.stop();
}

std::string Gateway::status_line() const {
  std::size_t up = 0, online = 0;
  for (const auto& b : buses_) up += b->counters().link_up ? 1 : 0;
  for (std::size_t i = 0; i < image_.size(); ++i)
    online += image_.node(static_cast<int>(i)).state == NodeState::online ? 1 : 0;
  return fmt::format("buses up {}/{}, nodes online {}/{}, clients {}", up, buses_.size(), online,
                     image_.size(), server_ ? server_->stats().clients_connected : 0);
}

}  // namespace fieldgate
