#include "gateway/lifecycle/daemon.hpp"

#include <iostream>

#include "gateway/bus/wire_trace.hpp"
#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

std::shared_ptr<const LoadedConfig> load_config_or_report(const std::string& path) {
  Diagnostics diagnostics;
  auto loaded = load_gateway_config(path, diagnostics);
  if (!loaded) {
    std::cerr << diagnostics.to_text();
    std::cerr << fmt::format("{}: {} error(s)\n", path, diagnostics.errors().size());
    return nullptr;
  }
  for (const auto& w : loaded->gateway.warnings) log::warning("{}", w);
  return std::make_shared<const LoadedConfig>(std::move(*loaded));
}

Daemon::Daemon(std::string config_path, std::shared_ptr<const LoadedConfig> config)
    : config_path_(std::move(config_path)),
      gateway_(std::make_unique<Gateway>(io_, std::move(config))),
      notifier_(
          io_.get_executor(), [this] { return gateway_->status_line(); },
          [this] { return gateway_->all_buses_attempted(); }),
      signals_(io_, SIGINT, SIGTERM, SIGHUP) {
  signals_.add(SIGUSR2);
}

Daemon::~Daemon() = default;

int Daemon::run() {
  try {
    gateway_->start();
  } catch (const boost::system::system_error& e) {
    log::error("modbus: cannot listen: {}", e.code().message());
    return 1;
  }
  notifier_.start();
  wait_for_signal();
  io_.run();
  return 0;
}

void Daemon::wait_for_signal() {
  signals_.async_wait([this](const boost::system::error_code& ec, int signal) {
    if (ec) return;
    if (signal == SIGHUP) {
      reload();
      wait_for_signal();
      return;
    }
    if (signal == SIGUSR2) {
      log::notice("SIGUSR2: wire trace now {} for every bus",
                  WireTrace::toggle_all() ? "on" : "off");
      wait_for_signal();
      return;
    }
    log::notice("signal {}: stopping", signal);
    notifier_.stopping();
    notifier_.stop();
    gateway_->stop();
    io_.stop();
  });
}

void Daemon::reload() {
  log::notice("SIGHUP: reloading {}", config_path_);
  notifier_.reloading();
  Diagnostics diagnostics;
  auto loaded = load_gateway_config(config_path_, diagnostics);
  if (!loaded) {
    for (const auto& e : diagnostics.errors())
      log::error("reload rejected: {}: {}", to_string(e.mark), e.message);
    log::error("reload rejected: {} error(s); the running configuration stays in force",
               diagnostics.errors().size());
    notifier_.reloaded();
    return;
  }
  for (const auto& w : loaded->gateway.warnings) log::warning("{}", w);
  const std::string summary =
      gateway_->apply(std::make_shared<const LoadedConfig>(std::move(*loaded)));
  log::notice("reloaded: {}", summary);
  notifier_.reloaded();
}

}  // namespace fieldgate
