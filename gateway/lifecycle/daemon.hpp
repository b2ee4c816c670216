#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "gateway/config/config_loader.hpp"
#include "gateway/gateway.hpp"
#include "gateway/lifecycle/reload_verdict.hpp"
#include "gateway/lifecycle/service_notifier.hpp"

namespace fieldgate {

// The process: one io_context, the gateway, systemd notification and signals. SIGINT/SIGTERM
// stop; SIGHUP reloads the configuration file (validated in full first; on any error the old
// configuration stays in force); SIGUSR2 toggles the wire trace of every bus. With a runtime
// directory, every reload's verdict is written there for `fieldgate reload` (reload_verdict.hpp).
class Daemon {
 public:
  Daemon(std::string config_path, std::shared_ptr<const LoadedConfig> config,
         std::optional<std::filesystem::path> runtime_dir = std::nullopt);
  ~Daemon();
  // Returns the exit code.
  int run();

 private:
  void wait_for_signal();
  void reload();
  void publish_verdict();
  std::string status_line() const;

  std::string config_path_;
  std::optional<std::filesystem::path> verdict_path_;
  ReloadVerdict verdict_;
  bool verdict_write_failed_ = false;
  asio::io_context io_{1};
  std::unique_ptr<Gateway> gateway_;
  ServiceNotifier notifier_;
  asio::signal_set signals_;
};

// Loads a configuration and prints every error (file:line:column) to stderr.
std::shared_ptr<const LoadedConfig> load_config_or_report(const std::string& path);

}  // namespace fieldgate
