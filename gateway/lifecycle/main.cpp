#include <fmt/ranges.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <iostream>

#include "drivers/protocol_family.hpp"
#include "drivers/protocol_file/protocol_loader.hpp"
#include "gateway/config/config_loader.hpp"
#include "gateway/config/device_writes.hpp"
#include "gateway/console/console_port.hpp"
#include "gateway/lifecycle/daemon.hpp"
#include "gateway/lifecycle/log.hpp"
#include "gateway/lifecycle/reload_command.hpp"
#include "gateway/lifecycle/reload_verdict.hpp"
#include "gateway/modbus/modbus_rtu_port.hpp"
#include "gateway/register_map/profile_units_document.hpp"
#include "gateway/sparkplug/sparkplug_spy.hpp"
#include "mapping/register_map_document.hpp"
#include "mapping/yaml_reader.hpp"

using namespace fieldgate;

namespace {

// The group to watch: from --broker and --group, else the configuration's sparkplug: section.
int run_spy(const std::string& broker, const std::string& group, const std::string& config_path) {
  sparkplug::SparkplugConfig c;
  if (broker.empty()) {
    auto config = load_config_or_report(config_path);
    if (!config) return 1;
    c = config->gateway.sparkplug;
    if (c.group_id.empty()) {
      std::cerr << "fieldgate sparkplug-spy: " << config_path
                << " has no sparkplug: section; give --broker and --group\n";
      return 2;
    }
    if (!group.empty()) c.group_id = group;
  } else {
    if (group.empty()) {
      std::cerr << "fieldgate sparkplug-spy: --broker needs --group\n";
      return 2;
    }
    // The section's own parser checks the URL and the ID, so both read as in a gateway file.
    Diagnostics d;
    YamlReader reader("sparkplug-spy", d);
    YAML::Node node;
    node["broker"] = broker;
    node["group_id"] = group;
    node["edge_node_id"] = "sparkplug-spy";
    sparkplug::parse_sparkplug_config(reader, node, c);
    if (!d.ok()) {
      std::cerr << d.to_text();
      return 2;
    }
  }
  return sparkplug::run_sparkplug_spy(c, std::cout);
}

int run_check(const std::string& path) {
  auto config = load_config_or_report(path);
  if (!config) return 1;
  const auto& gateway = config->gateway;
  std::size_t nodes = 0;
  for (const auto& b : gateway.buses) nodes += b.nodes.size();
  std::size_t units = 0;
  for (std::size_t l = 0; l < gateway.listener_count(); ++l)
    units += config->map_of(l).units().size();
  std::cout << fmt::format("{}: ok ({} bus(es), {} node(s), {} unit ID(s))\n", path,
                           gateway.buses.size(), nodes, units);
  for (const auto& bus : gateway.buses)
    for (const auto& line : device_writes_on(bus.protocol, bus.device_writes))
      std::cout << fmt::format("  bus {} writes to its devices on its own: {}\n", bus.name, line);
  if (gateway.listener_count() > 1)
    for (std::size_t l = 0; l < gateway.listener_count(); ++l) {
      const auto& m = gateway.listener_modbus(l);
      std::cout << fmt::format("  listener {} on {}:{}: {} unit ID(s)\n", gateway.listener_name(l),
                               m.address, m.port, config->map_of(l).units().size());
    }
  return 0;
}

std::vector<ListenerMap> listener_maps(const LoadedConfig& config) {
  std::vector<ListenerMap> maps;
  for (std::size_t l = 0; l < config.gateway.listener_count(); ++l) {
    const auto& m = config.gateway.listener_modbus(l);
    maps.push_back({config.gateway.listener_name(l), fmt::format("{}:{}", m.address, m.port),
                    &config.map_of(l)});
  }
  return maps;
}

// Protocol files of the given directories; a directory that is not there is said, not an error
// (the default one exists only where the package is installed).
void list_protocol_files(const std::vector<std::string>& dirs) {
  for (const auto& dir : dirs) {
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) {
      std::cout << fmt::format("Protocol files: no directory {}\n", dir);
      continue;
    }
    Diagnostics d;
    protocol_file::ProtocolLibrary library;
    library.load_directory(dir, d);
    std::cout << fmt::format("Protocol files in {} (a bus's protocol, a model's family):\n", dir);
    for (const auto& spec : library.all())
      std::cout << fmt::format("  {} ({} command(s), {}): {}\n", spec->name, spec->commands.size(),
                               std::filesystem::path(spec->file).filename().string(),
                               spec->description);
    if (!d.ok()) std::cout << "  refused (fieldgate check --protocol FILE):\n" << d.to_text();
  }
}

int run_check_protocols(const std::vector<std::string>& files) {
  int status = 0;
  for (const auto& file : files) {
    Diagnostics d;
    const auto spec = protocol_file::load_protocol_file(file, d);
    if (!spec) {
      std::cerr << d.to_text();
      status = 1;
      continue;
    }
    std::cout << fmt::format("{}: ok (protocol {}, {} command(s), alignment proof {})\n", file,
                             spec->name, spec->commands.size(), [&] {
                               std::string steps;
                               for (const auto& step : spec->alignment)
                                 steps += (steps.empty() ? "" : " then ") + step.command;
                               return steps;
                             }());
  }
  return status;
}

int run_models(const std::string& family, const std::vector<std::string>& protocol_dirs) {
  if (family.empty()) {
    std::cout << "Families (fieldgate models --options FAMILY describes a family's model "
                 "options):\n";
    for (const auto& name : family_names())
      std::cout << fmt::format("  {} ({} model option(s))\n", name,
                               make_family(name)->model_options().size());
    list_protocol_files(protocol_dirs);
    return 0;
  }
  const auto names = family_names();
  if (std::find(names.begin(), names.end(), family) == names.end()) {
    std::string known;
    for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
    std::cerr << fmt::format("fieldgate models: unknown family '{}' (known: {})\n", family, known);
    return 2;
  }
  std::cout << describe_model_options(family, make_family(family)->model_options());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fieldgate: field links to a Modbus register map"};
  std::string config_path = FIELDGATE_DEFAULT_CONFIG;
  bool verbose = false;
  app.set_version_flag("--version", "fieldgate " FIELDGATE_VERSION_TEXT);
  auto* config_option = app.add_option("-c,--config", config_path, "gateway configuration (YAML)")
                            ->capture_default_str();
  app.add_flag("-v,--verbose", verbose, "log debug detail");
  std::string runtime_dir;
  app.add_option("--runtime-dir", runtime_dir,
                 "where the reload verdict is written (default: $RUNTIME_DIRECTORY)");
  // The command line over the environment over the configuration's console: listen: port.
  std::uint16_t console_port_option = 0;
  auto* console_port_given =
      app.add_option("--console-port", console_port_option,
                     "the web console's port, in place of the configuration's console: listen: "
                     "port (also FIELDGATE_CONSOLE_PORT)")
          ->envname("FIELDGATE_CONSOLE_PORT")
          ->check(CLI::Range(1, 65535));
  auto* check = app.add_subcommand("check", "validate a configuration without opening any port");
  std::string check_path = FIELDGATE_DEFAULT_CONFIG;
  auto* check_given = check->add_option("config", check_path, "gateway configuration (YAML)")
                          ->capture_default_str();
  auto* check_named = check->add_option("-c,--config", check_path, "the same, by name");
  std::vector<std::string> check_protocols;
  check->add_option("--protocol", check_protocols,
                    "check protocol files alone (docs/protocol-files.md), not a configuration");
  auto* map = app.add_subcommand("map", "write the register map document for the PLC programmer");
  std::string map_path = FIELDGATE_DEFAULT_CONFIG;
  std::string map_format = "md";
  auto* map_given =
      map->add_option("config", map_path, "gateway configuration (YAML)")->capture_default_str();
  auto* map_named = map->add_option("-c,--config", map_path, "the same, by name");
  map->add_option("--format", map_format, "md or csv")->check(CLI::IsMember({"md", "csv"}));
  bool map_profile = false;
  map->add_flag("--profile", map_profile,
                "write the axis profile page (with a config: and its profile units)");
  auto* models = app.add_subcommand("models", "list the protocol families and their model options");
  std::string models_family;
  models->add_option("--options", models_family, "describe this family's model options");
  std::vector<std::string> models_protocols{FIELDGATE_PROTOCOL_DIR};
  models->add_option("--protocols", models_protocols, "list the protocol files of this directory")
      ->capture_default_str();
  auto* spy = app.add_subcommand(
      "sparkplug-spy",
      "decode a Sparkplug B group live: every birth, death, data and command on the broker");
  std::string spy_broker, spy_group;
  spy->add_option("--broker", spy_broker,
                  "mqtt://HOST[:PORT] or mqtts://... (default: the configuration's broker)");
  spy->add_option("--group", spy_group, "group ID (default: the configuration's)");
  auto* reload = app.add_subcommand(
      "reload", "check the running daemon's configuration, reload it, and wait for its verdict");
  ReloadOptions reload_options;
  reload->add_option("--pid", reload_options.pid, "the daemon's pid (systemd: $MAINPID)");
  reload->add_option("--runtime-dir", reload_options.runtime_dir,
                     "the daemon's runtime directory (default: $RUNTIME_DIRECTORY)");
  reload->add_flag("!--no-check", reload_options.check_first,
                   "send SIGHUP even when the file does not pass the check");
  double reload_timeout = 30;
  reload->add_option("--timeout", reload_timeout, "seconds to wait for the verdict")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  // `fieldgate --config X check` means X, as `fieldgate check X` and `fieldgate check --config X`.
  if (config_option->count() > 0) {
    if (check_given->count() == 0 && check_named->count() == 0) check_path = config_path;
    if (map_given->count() == 0 && map_named->count() == 0) map_path = config_path;
  }
  if (*reload) {
    reload_options.timeout =
        std::chrono::milliseconds(static_cast<long long>(reload_timeout * 1000));
    return run_reload(reload_options);
  }
  if (*models) return run_models(models_family, models_protocols);
  if (*spy) return run_spy(spy_broker, spy_group, config_path);
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
        listener_maps(*config),
        map_format == "csv" ? DocumentFormat::csv : DocumentFormat::markdown);
    if (map_format == "md") std::cout << describe_modbus_rtu(*config);
    return 0;
  }
  if (verbose) log::set_verbosity(log::Level::debug);
  if (*check && !check_protocols.empty()) return run_check_protocols(check_protocols);
  if (*check) return run_check(check_path);
  auto config = load_config_or_report(config_path);
  if (!config) {
    std::cerr << "nothing was started\n";
    return 1;
  }
  if (console_port_given->count() > 0) {
    set_console_port_override(console_port_option);
    if (!config->gateway.console.enabled)
      log::warning(
          "console port {}: {} has the console off (no console: section, or "
          "enabled: false), so nothing listens on it",
          console_port_option, config_path);
  }
  Daemon daemon(config_path, std::move(config), runtime_directory(runtime_dir));
  return daemon.run();
}
