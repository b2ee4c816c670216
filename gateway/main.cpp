#include <systemd/sd-daemon.h>
#include <CLI/CLI.hpp>

#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>

#include <iostream>

#include "gateway/config_loader.hpp"
#include "gateway/gateway.hpp"
#include "gateway/log.hpp"

using namespace fieldgate;

namespace {

std::shared_ptr<const LoadedConfig> load_or_report(const std::string& path) {
  Diagnostics diagnostics;
  auto loaded = load_gateway_config(path, diagnostics);
  if (!loaded) {
    std::cerr << diagnostics.to_text();
    std::cerr << fmt::format("{}: {} error(s); nothing was started\n", path,
                             diagnostics.errors().size());
    return nullptr;
  }
  for (const auto& w : loaded->gateway.warnings) std::cerr << "warning: " << w << "\n";
  return std::make_shared<const LoadedConfig>(std::move(*loaded));
}

int run_check(const std::string& path) {
  auto config = load_or_report(path);
  if (!config) return 1;
  std::size_t nodes = 0;
  for (const auto& b : config->gateway.buses) nodes += b.nodes.size();
  std::cout << fmt::format("{}: ok ({} bus(es), {} node(s), {} unit ID(s))\n", path,
                           config->gateway.buses.size(), nodes,
                           config->register_map.units().size());
  return 0;
}

int run_daemon(const std::string& path) {
  auto config = load_or_report(path);
  if (!config) return 1;
  asio::io_context io(1);
  Gateway gateway(io, config);
  try {
    gateway.start();
  } catch (const boost::system::system_error& e) {
    log::error("modbus: cannot listen on {}:{}: {}", config->gateway.modbus.address,
               config->gateway.modbus.port, e.code().message());
    return 1;
  }
  asio::signal_set signals(io, SIGINT, SIGTERM);
  signals.async_wait([&](const boost::system::error_code& ec, int signal) {
    if (ec) return;
    log::notice("signal {}: stopping", signal);
    sd_notify(0, "STOPPING=1");
    gateway.stop();
    io.stop();
  });
  sd_notify(0, "READY=1");
  log::notice("fieldgate running: {}", gateway.status_line());
  io.run();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fieldgate: field links to a Modbus register map"};
  std::string config_path;
  bool verbose = false;
  app.add_option("-c,--config", config_path, "gateway configuration (YAML)");
  app.add_flag("-v,--verbose", verbose, "log every state change and debug detail");
  auto* check = app.add_subcommand("check", "validate a configuration without opening any port");
  std::string check_path;
  check->add_option("config", check_path, "gateway configuration (YAML)")->required();
  CLI11_PARSE(app, argc, argv);
  if (verbose) log::set_verbosity(log::Level::debug);
  if (*check) return run_check(check_path);
  if (config_path.empty()) {
    std::cerr << "fieldgate: --config FILE is required (or 'fieldgate check FILE')\n" << app.help();
    return 2;
  }
  return run_daemon(config_path);
}
