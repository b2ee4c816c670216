#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/steady_timer.hpp>

#include <functional>
#include <string>

namespace fieldgate {

namespace asio = boost::asio;

// Talks to systemd (sd_notify): READY=1 once the gateway says it is ready, WATCHDOG=1 from a
// timer on the event loop itself (a stuck loop stops the pings and systemd restarts us),
// STATUS= with a one-line summary, RELOADING=1 and STOPPING=1. Without NOTIFY_SOCKET every
// call is a no-op.
class ServiceNotifier {
 public:
  using StatusLine = std::function<std::string()>;
  using ReadyCheck = std::function<bool()>;

  ServiceNotifier(asio::any_io_executor executor, StatusLine status, ReadyCheck ready);
  void start();
  void reloading();
  void reloaded();
  void stopping();
  void stop();

 private:
  void tick();

  asio::steady_timer timer_;
  StatusLine status_;
  ReadyCheck ready_;
  std::chrono::microseconds watchdog_{0};
  std::chrono::steady_clock::time_point last_ping_{};
  std::chrono::steady_clock::time_point last_status_{};
  std::string last_status_text_;
  bool ready_sent_ = false;
  bool stopped_ = false;
};

}  // namespace fieldgate
