#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "gateway/config/config_loader.hpp"
#include "gateway/gateway.hpp"
#include "gateway/lifecycle/reload_verdict.hpp"
#include "gateway/lifecycle/service_notifier.hpp"

namespace fieldgate {

// The process: one io_context, the gateway, systemd notification and signals. SIGINT/SIGTERM
// stop; SIGHUP reloads the configuration file (validated in full first; on any error the old
// configuration stays in force); SIGUSR2 toggles the wire trace of every bus. With a runtime
// directory, every reload's verdict is written there for `fieldgate reload` (reload_verdict.hpp).
// A reload reads and checks the file on a thread of its own and puts it in force on the event
// loop, so Modbus answers wait only for the swap; a SIGHUP during a load is taken once it ends.
class Daemon {
 public:
  Daemon(std::string config_path, std::shared_ptr<const LoadedConfig> config,
         std::optional<std::filesystem::path> runtime_dir = std::nullopt);
  ~Daemon();
  // Returns the exit code.
  int run();

 private:
  void wait_for_signal();
  // What a reload's loading thread hands to the event loop.
  struct Loaded {
    std::string fingerprint;
    std::optional<LoadedConfig> config;
    std::vector<std::string> errors;  // file:line:column: message
  };
  void reload();
  void put_in_force(Loaded loaded);
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
  bool loading_ = false;
  bool reload_again_ = false;  // a SIGHUP came while a file was being loaded
  // Last: joined before the io_context it posts to goes.
  std::jthread loader_;
};

// Loads a configuration and prints every error (file:line:column) to stderr.
std::shared_ptr<const LoadedConfig> load_config_or_report(const std::string& path);

}  // namespace fieldgate
