#include "gateway/lifecycle/daemon.hpp"

#include <malloc.h>
#include <unistd.h>

#include <boost/asio/post.hpp>

#include <iostream>

#include "gateway/bus/wire_trace.hpp"
#include "gateway/config/device_writes.hpp"
#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

std::shared_ptr<const LoadedConfig> load_config_or_report(const std::string& path) {
  Diagnostics diagnostics;
  auto loaded = load_gateway_config(path, diagnostics);
  if (!loaded) {
    // At err in the journal (ExecStartPre=, ExecReload= and the daemon), one entry each.
    for (const auto& e : diagnostics.errors())
      log::error("{}: error: {}", to_string(e.mark), e.message);
    log::error("{}: {} error(s)", path, diagnostics.errors().size());
    return nullptr;
  }
  for (const auto& w : loaded->gateway.warnings) log::warning("{}", w);
  return std::make_shared<const LoadedConfig>(std::move(*loaded));
}

namespace {

// The shipped configuration has no bus, so a fresh install polls and writes nothing until the
// site has written its own: say so, or the silence looks like a fault.
void log_when_no_bus(const GatewayConfig& config) {
  if (!config.buses.empty()) return;
  log::notice(
      "{}: no field bus configured: no serial port or CAN interface is opened and nothing is "
      "written to any device; write the site's buses there (examples in "
      "/usr/share/doc/fieldgate/examples) and reload",
      config.file);
}

// Writes no Modbus client asked for (writes_enabled does not stop them): in the journal.
void log_device_writes(const GatewayConfig& config) {
  for (const auto& bus : config.buses)
    for (const auto& line : device_writes_on(bus.protocol, bus.device_writes))
      log::notice("bus {}: writes to its devices on its own (device_writes) {}", bus.name, line);
}

}  // namespace

Daemon::Daemon(std::string config_path, std::shared_ptr<const LoadedConfig> config,
               std::optional<std::filesystem::path> runtime_dir)
    : config_path_(std::move(config_path)),
      gateway_(std::make_unique<Gateway>(io_, config)),
      notifier_(
          io_.get_executor(), [this] { return status_line(); },
          [this] { return gateway_->all_buses_attempted(); }),
      signals_(io_, SIGINT, SIGTERM, SIGHUP) {
  signals_.add(SIGUSR2);
  // A reload loads on a thread of its own (reload()); in a malloc arena of its own, that would
  // keep about 2 MB resident after the first reloads for nothing.
  ::mallopt(M_ARENA_MAX, 1);
  if (runtime_dir) verdict_path_ = *runtime_dir / kVerdictFileName;
  verdict_.pid = static_cast<long>(::getpid());
  verdict_.config_file = config_path_;
  verdict_.config_id = config_fingerprint(config_path_);
  log_when_no_bus(config->gateway);
  log_device_writes(config->gateway);
}

Daemon::~Daemon() = default;

int Daemon::run() {
  try {
    gateway_->start();
  } catch (const boost::system::system_error& e) {
    log::error("modbus: cannot listen: {}", e.code().message());
    return 1;
  }
  log::notice("{} in force: {}", verdict_.in_force(), config_path_);
  publish_verdict();
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
  if (loading_) {
    reload_again_ = true;
    return;
  }
  log::notice("SIGHUP: reloading {}", config_path_);
  notifier_.reloading();
  loading_ = true;
  if (loader_.joinable()) loader_.join();  // the previous load, long since posted its result
  loader_ = std::jthread([this, path = config_path_] {
    Loaded loaded;
    loaded.fingerprint = config_fingerprint(path);
    Diagnostics diagnostics;
    loaded.config = load_gateway_config(path, diagnostics);
    if (!loaded.config)
      for (const auto& e : diagnostics.errors())
        loaded.errors.push_back(fmt::format("{}: {}", to_string(e.mark), e.message));
    asio::post(io_,
               [this, loaded = std::move(loaded)]() mutable { put_in_force(std::move(loaded)); });
  });
}

void Daemon::put_in_force(Loaded loaded) {
  loading_ = false;
  ++verdict_.reload;
  verdict_.messages.clear();
  if (!loaded.config) {
    for (const auto& e : loaded.errors) {
      log::error("reload rejected: {}", e);
      verdict_.messages.push_back(e);
    }
    log::error("reload rejected: {} error(s); {} stays in force", loaded.errors.size(),
               verdict_.in_force());
    verdict_.result = ReloadVerdict::Result::rejected;
  } else {
    for (const auto& w : loaded.config->gateway.warnings) log::warning("{}", w);
    log_when_no_bus(loaded.config->gateway);
    log_device_writes(loaded.config->gateway);
    const std::string summary =
        gateway_->apply(std::make_shared<const LoadedConfig>(std::move(*loaded.config)));
    ++verdict_.config_number;
    verdict_.config_id = loaded.fingerprint;
    verdict_.result = ReloadVerdict::Result::accepted;
    verdict_.messages.push_back(summary);
    log::notice("reloaded: {} in force: {}", verdict_.in_force(), summary);
  }
  publish_verdict();
  notifier_.reloaded();
  if (reload_again_) {
    reload_again_ = false;
    reload();
  }
}

void Daemon::publish_verdict() {
  if (!verdict_path_) return;
  std::string error;
  if (write_verdict_file(*verdict_path_, verdict_, error)) {
    verdict_write_failed_ = false;
  } else if (!verdict_write_failed_) {
    verdict_write_failed_ = true;
    log::warning("{}: `fieldgate reload` cannot learn the verdict", error);
  }
}

std::string Daemon::status_line() const {
  std::string text = verdict_.in_force();
  if (verdict_.result == ReloadVerdict::Result::rejected)
    text += fmt::format(" (reload #{} refused)", verdict_.reload);
  return text + "; " + gateway_->status_line();
}

}  // namespace fieldgate
