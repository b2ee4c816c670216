#include "gateway/lifecycle/service_notifier.hpp"

#include <systemd/sd-daemon.h>

#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

namespace {
using Clock = std::chrono::steady_clock;
constexpr auto kTick = std::chrono::milliseconds(50);
constexpr auto kStatusEvery = std::chrono::seconds(5);
}  // namespace

ServiceNotifier::ServiceNotifier(asio::any_io_executor executor, StatusLine status,
                                 ReadyCheck ready)
    : timer_(executor), status_(std::move(status)), ready_(std::move(ready)) {}

void ServiceNotifier::start() {
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0) {
    watchdog_ = std::chrono::microseconds(usec);
    log::info("systemd watchdog every {} ms", usec / 1000);
  }
  tick();
}

void ServiceNotifier::tick() {
  if (stopped_) return;
  const auto now = Clock::now();
  if (!ready_sent_ && ready_()) {
    ready_sent_ = true;
    last_status_text_ = status_();
    sd_notifyf(0, "READY=1\nSTATUS=%s", last_status_text_.c_str());
    last_status_ = now;
    log::notice("ready: {}", last_status_text_);
  }
  if (watchdog_.count() > 0 && now - last_ping_ >= watchdog_ / 2) {
    sd_notify(0, "WATCHDOG=1");
    last_ping_ = now;
  }
  if (ready_sent_ && now - last_status_ >= kStatusEvery) {
    const std::string text = status_();
    if (text != last_status_text_) sd_notifyf(0, "STATUS=%s", text.c_str());
    last_status_text_ = text;
    last_status_ = now;
  }
  timer_.expires_after(kTick);
  timer_.async_wait([this](const boost::system::error_code& ec) {
    if (!ec) tick();
  });
}

void ServiceNotifier::reloading() {
  // systemd 253+ wants MONOTONIC_USEC with RELOADING=1; older ones ignore it.
  sd_notifyf(0, "RELOADING=1\nMONOTONIC_USEC=%llu\nSTATUS=reloading configuration",
             static_cast<unsigned long long>(std::chrono::duration_cast<std::chrono::microseconds>(
                                                 Clock::now().time_since_epoch())
                                                 .count()));
}

void ServiceNotifier::reloaded() {
  last_status_text_ = status_();
  sd_notifyf(0, "READY=1\nSTATUS=%s", last_status_text_.c_str());
}

void ServiceNotifier::stopping() {
  sd_notify(0, "STOPPING=1\nSTATUS=stopping");
}

void ServiceNotifier::stop() {
  stopped_ = true;
  timer_.cancel();
}

}  // namespace fieldgate
