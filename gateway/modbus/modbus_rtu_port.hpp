// The gateway's Modbus RTU port: the server built from the modbus_rtu: section, kept across
// reloads where the port's settings allow, and its description for `fieldgate map`.
#pragma once

#include <memory>
#include <string>

#include <boost/asio/io_context.hpp>

#include "gateway/config/config_loader.hpp"
#include "gateway/modbus/rtu_server.hpp"

namespace fieldgate {

// The served units (the section's list, else every unit of the map) and the broadcast stop's
// writes: each served unit whose model is listed gets its stop action's code; an action marked
// bus_wide is sent to one unit per bus, since every node on that bus hears it.
modbus::ModbusRtuServerOptions rtu_server_options(const LoadedConfig& config);

// A Markdown section for the register map document; empty without a modbus_rtu: section.
std::string describe_modbus_rtu(const LoadedConfig& config);

class ModbusRtuPort {
 public:
  explicit ModbusRtuPort(asio::io_context& io) : io_(io) {}

  // Starts, reconfigures, replaces or stops the server as the configuration says.
  void apply(const LoadedConfig& config, std::shared_ptr<modbus::RequestHandler> handler);
  void stop();
  const modbus::ModbusRtuServer* server() const { return server_.get(); }

 private:
  asio::io_context& io_;
  std::unique_ptr<modbus::ModbusRtuServer> server_;
};

}  // namespace fieldgate
