#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>

#include <memory>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "gateway/bus/bus.hpp"
#include "gateway/config/config_loader.hpp"
#include "gateway/console/console_server.hpp"
#include "gateway/image/process_image.hpp"
#include "gateway/metrics/metrics_server.hpp"
#include "gateway/modbus/modbus_rtu_port.hpp"
#include "gateway/modbus/tcp_server.hpp"
#include "gateway/register_map/action_runner.hpp"
#include "gateway/register_map/register_map_handler.hpp"

namespace fieldgate {

class FleetWatch;

namespace sparkplug {
class EdgeNode;
struct SessionStats;
}  // namespace sparkplug

// What the metrics and console HTTP servers turned away, since the daemon started: a reload that
// restarts a server (the console, at every reload) carries its counts over.
struct HttpServerCounts {
  std::uint64_t refused = 0;       // closed at once: every slot held, none to evict
  std::uint64_t evicted = 0;       // closed before its request had come, to make room
  std::uint64_t denied = 0;        // metrics: connections not on the allow list; console: 403s
  std::uint64_t bad_requests = 0;  // answered 400, 413 or 431
};

// The running gateway: buses, process image, actions and the Modbus listeners (one TCP server
// per listener, each with its own unit-ID space) on one io_context.
// A configuration in force is a generation; a reload builds the next one, keeping every bus
// whose configuration did not change (and its nodes' state) and the Modbus clients. A bus whose
// nodes alone changed takes them in place where it can (Bus::reconfigure).
class Gateway {
 public:
  Gateway(asio::io_context& io, std::shared_ptr<const LoadedConfig> config);
  ~Gateway();

  // Binds every Modbus listener (throws boost::system::system_error if one cannot) and starts
  // every bus.
  void start();
  void stop();
  // Puts a validated configuration in force; returns a one-line summary of what changed.
  std::string apply(std::shared_ptr<const LoadedConfig> config);

  const LoadedConfig& config() const { return *current_->config; }
  const ProcessImage& image() const { return current_->image; }
  struct Listener {
    std::string name;
    std::unique_ptr<modbus::ModbusTcpServer> server;
  };
  // In the configuration's order; the first is the default listener (`modbus:`).
  const std::vector<Listener>& listeners() const { return listeners_; }
  const modbus::ModbusTcpServer& server() const { return *listeners_.at(0).server; }
  // The request handler serving a listener's unit-ID space in the configuration in force, for
  // any server attached to that listener (TCP here; a serial port could take the same); null
  // if no listener has that name.
  std::shared_ptr<modbus::RequestHandler> handler(std::string_view listener) const;
  // Null without a modbus_rtu: section.
  const modbus::ModbusRtuServer* rtu_server() const { return rtu_.server(); }
  const std::vector<std::shared_ptr<Bus>>& buses() const { return current_->buses; }
  std::string status_line() const;
  // Every bus has finished its first attempt to open its link (READY=1 waits for this).
  bool all_buses_attempted() const;
  // Configurations a reload replaced that something still runs on (a Modbus request, a
  // Sparkplug command, an action or its completion watch); each is freed once nothing does.
  std::size_t retired_generations() const { return retired_.size(); }
  HttpServerCounts metrics_http_counts() const;
  HttpServerCounts console_http_counts() const;
  // The Sparkplug B session, when enabled.
  const sparkplug::SessionStats* sparkplug_stats() const;

 private:
  struct Generation {
    // Work the generation's ActionRunner has under way (see build()).
    std::shared_ptr<std::size_t> action_work = std::make_shared<std::size_t>(0);
    std::shared_ptr<const LoadedConfig> config;
    std::vector<std::shared_ptr<Bus>> buses;
    std::vector<int> bus_of_node;
    ProcessImage image;
    std::unique_ptr<ActionRunner> actions;
    std::shared_ptr<ControlService> control;                    // every front door's writes
    std::vector<std::shared_ptr<RegisterMapHandler>> handlers;  // by listener index
    std::size_t reconfigured = 0;  // buses a reload kept with their nodes changed in place
  };

  // A generation's handler and control service as handed out: each copy keeps the whole
  // generation alive, so a request or command under way finishes on the one it started with.
  static std::shared_ptr<RegisterMapHandler> handler_of(const std::shared_ptr<Generation>& g,
                                                        std::size_t listener);
  static std::shared_ptr<ControlService> control_of(const std::shared_ptr<Generation>& g);
  // Builds a generation, taking buses from `previous` whose signature is unchanged.
  std::shared_ptr<Generation> build(std::shared_ptr<const LoadedConfig> config,
                                    Generation* previous, std::vector<std::shared_ptr<Bus>>& fresh);
  // The one place a listener's handler is made (every server of the listener shares it).
  std::shared_ptr<RegisterMapHandler> make_handler(Generation& g, std::size_t listener);
  // The nodes of the configuration a reload replaces, by name: global index and configuration.
  using PreviousNodes = std::unordered_map<std::string, std::pair<int, const NodeConfig*>>;
  static void carry_over(const Generation& previous, const PreviousNodes& previous_nodes,
                         const BusConfig& bus_config, const Bus& bus);
  // What DCMD may change on each node: what the Modbus listener that owns the node allows.
  static std::vector<WritePolicy> node_policies(const Generation& g);
  // The handler of the listener whose unit-ID space the RTU port serves (null without one).
  static std::shared_ptr<modbus::RequestHandler> rtu_handler(const std::shared_ptr<Generation>& g);
  static modbus::ModbusTcpServerOptions server_options(const GatewayConfig& config,
                                                       std::size_t listener);
  std::unique_ptr<modbus::ModbusTcpServer> open_listener(const std::shared_ptr<Generation>& g,
                                                         std::size_t listener);
  std::string apply_listeners(const std::shared_ptr<Generation>& next);
  // Whether anything still runs on a generation that nobody else holds.
  static bool idle(const Generation& g);
  // Frees the retired generations nothing runs on; looks again later while some remain.
  void sweep_retired();
  void spawn(const std::shared_ptr<Bus>& bus);
  void start_metrics();
  void start_console();
  void start_sparkplug();

  asio::io_context& io_;
  std::shared_ptr<Generation> current_;
  // Replaced generations something still runs on (sweep_retired).
  std::vector<std::shared_ptr<Generation>> retired_;
  asio::steady_timer sweep_timer_{io_};
  std::vector<Listener> listeners_;
  ModbusRtuPort rtu_{io_};
  std::unique_ptr<MetricsServer> metrics_;
  std::unique_ptr<ConsoleServer> console_;
  HttpServerCounts metrics_before_;  // of the metrics servers a reload replaced
  HttpServerCounts console_before_;
  std::unique_ptr<FleetWatch> fleet_;  // the console's view of the Sparkplug group
  std::unique_ptr<sparkplug::EdgeNode> sparkplug_;
  std::vector<std::shared_ptr<Bus>> pending_start_;
};

}  // namespace fieldgate
