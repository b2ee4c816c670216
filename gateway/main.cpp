#include <CLI/CLI.hpp>

#include <iostream>

#include "gateway/config_loader.hpp"
#include "gateway/daemon.hpp"
#include "gateway/log.hpp"
#include "gateway/profile_units_document.hpp"
#include "mapping/register_map_document.hpp"

using namespace fieldgate;

namespace {

int run_check(const std::string& path) {
  auto config = load_config_or_report(path);
  if (!config) return 1;
  std::size_t nodes = 0;
  for (const auto& b : config->gateway.buses) nodes += b.nodes.size();
  std::cout << fmt::format("{}: ok ({} bus(es), {} node(s), {} unit ID(s))\n", path,
                           config->gateway.buses.size(), nodes,
                           config->register_map.units().size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fieldgate: field links to a Modbus register map"};
  std::string config_path;
  bool verbose = false;
  app.add_option("-c,--config", config_path, "gateway configuration (YAML)");
  app.add_flag("-v,--verbose", verbose, "log debug detail");
  auto* check = app.add_subcommand("check", "validate a configuration without opening any port");
  std::string check_path;
  check->add_option("config", check_path, "gateway configuration (YAML)")->required();
  auto* map = app.add_subcommand("map", "write the register map document for the PLC programmer");
  std::string map_path;
  std::string map_format = "md";
  map->add_option("config", map_path, "gateway configuration (YAML)");
  map->add_option("--format", map_format, "md or csv")->check(CLI::IsMember({"md", "csv"}));
  bool map_profile = false;
  map->add_flag("--profile", map_profile,
                "write the axis profile page (with a config: and its profile units)");
  CLI11_PARSE(app, argc, argv);
  if (*map && map_profile) {
    std::cout << write_axis_profile_document();
    if (map_path.empty()) return 0;
    auto config = load_config_or_report(map_path);
    if (!config) return 1;
    std::cout << write_profile_units_document(config->gateway);
    return 0;
  }
  if (*map && map_path.empty()) {
    std::cerr << "fieldgate map: a configuration is required (or --profile)\n";
    return 2;
  }
  if (*map) {
    auto config = load_config_or_report(map_path);
    if (!config) return 1;
    std::cout << write_register_map_document(
        config->register_map, map_format == "csv" ? DocumentFormat::csv : DocumentFormat::markdown);
    return 0;
  }
  if (verbose) log::set_verbosity(log::Level::debug);
  if (*check) return run_check(check_path);
  if (config_path.empty()) {
    std::cerr << "fieldgate: --config FILE is required (or 'fieldgate check FILE')\n" << app.help();
    return 2;
  }
  auto config = load_config_or_report(config_path);
  if (!config) {
    std::cerr << "nothing was started\n";
    return 1;
  }
  Daemon daemon(config_path, std::move(config));
  return daemon.run();
}
