#pragma once

#include <boost/asio/io_context.hpp>

#include <memory>
#include <vector>

#include "gateway/action_runner.hpp"
#include "gateway/bus.hpp"
#include "gateway/config_loader.hpp"
#include "gateway/modbus/tcp_server.hpp"
#include "gateway/process_image.hpp"
#include "gateway/register_map_handler.hpp"

namespace fieldgate {

// The running daemon: buses, process image, actions and the Modbus server on one io_context.
class Gateway {
 public:
  Gateway(asio::io_context& io, std::shared_ptr<const LoadedConfig> config);
  ~Gateway();

  // Binds the Modbus listener (throws boost::system::system_error if it cannot) and starts
  // every bus.
  void start();
  void stop();

  const ProcessImage& image() const { return image_; }
  const modbus::ModbusTcpServer& server() const { return *server_; }
  const std::vector<std::unique_ptr<Bus>>& buses() const { return buses_; }
  std::string status_line() const;

 private:
  Bus& bus_of(int node_index);

  asio::io_context& io_;
  std::shared_ptr<const LoadedConfig> config_;
  ProcessImage image_;
  std::vector<std::unique_ptr<Bus>> buses_;
  std::vector<int> bus_of_node_;
  ActionRunner actions_;
  std::shared_ptr<RegisterMapHandler> handler_;
  std::unique_ptr<modbus::ModbusTcpServer> server_;
};

}  // namespace fieldgate
