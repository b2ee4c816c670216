#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/posix/stream_descriptor.hpp>
#include <boost/asio/steady_timer.hpp>

#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "gateway/sparkplug/session_stats.hpp"
#include "gateway/sparkplug/sparkplug_config.hpp"

struct mosquitto;
struct mosquitto_message;

namespace fieldgate::sparkplug {

namespace asio = boost::asio;

// One MQTT client session on the gateway's io_context, through libmosquitto's external event
// loop interface: the socket is watched with a posix::stream_descriptor, mosquitto_loop_read/
// loop_write run when it is ready, mosquitto_loop_misc (keepalive) on a timer. Nothing blocks
// the io_context: the broker's name is resolved with asio before libmosquitto connects
// (non-blocking connect), and a lost session is retried with exponential back-off.
class MqttConnection {
 public:
  struct Will {
    std::string topic;
    std::string payload;
  };
  struct Handlers {
    // Called before every CONNECT: the will of that session (the NDEATH with its bdSeq).
    std::function<Will()> next_will;
    std::function<void()> connected;
    std::function<void()> disconnected;
    std::function<void(const std::string& topic, std::string_view payload)> message;
  };

  MqttConnection(asio::any_io_executor executor, const SparkplugConfig& config, Handlers handlers,
                 SessionStats& stats);
  ~MqttConnection();
  MqttConnection(const MqttConnection&) = delete;
  MqttConnection& operator=(const MqttConnection&) = delete;

  void start();
  // Sends DISCONNECT (the broker drops the will) and stops reconnecting.
  void stop();
  // Ends the session now (DISCONNECT) and connects again after the back-off.
  void restart();

  bool connected() const { return connected_; }
  bool publish(const std::string& topic, const std::string& payload, int qos, bool retain);
  bool subscribe(const std::string& filter, int qos);

 private:
  static void on_connect(mosquitto*, void* self, int rc);
  static void on_message(mosquitto*, void* self, const mosquitto_message* message);
  void deliver(std::function<void()> handler);
  void resolve_and_connect();
  void connect_to(const std::string& address);
  void watch_socket();
  void wait_readable();
  void wait_writable();
  void tick();
  // After every libmosquitto call: a failed call or a closed socket ends the session.
  void check(int rc, const char* what);
  void lost(const std::string& why);
  void schedule_reconnect();

  asio::any_io_executor executor_;
  SparkplugConfig config_;
  Handlers handlers_;
  SessionStats& stats_;
  mosquitto* mosq_ = nullptr;
  asio::ip::tcp::resolver resolver_;
  asio::posix::stream_descriptor socket_;
  asio::steady_timer misc_timer_;
  asio::steady_timer reconnect_timer_;
  std::chrono::microseconds backoff_;
  int fd_ = -1;  // libmosquitto's socket being watched (ours is a dup of it)
  bool connected_ = false;
  bool writing_ = false;
  bool running_ = false;
  // Handlers of pending waits see this to know their connection is gone.
  std::shared_ptr<int> epoch_ = std::make_shared<int>(0);
  // The epoch a wait was started in, captured by its handler: once a new socket, lost() or
  // stop() moved on (or the connection was destroyed), the handler does nothing.
  struct EpochMark {
    std::weak_ptr<int> epoch;
    int seen = 0;
    bool current() const {
      const auto e = epoch.lock();
      return e && *e == seen;
    }
  };
  EpochMark mark_epoch() const { return {epoch_, *epoch_}; }
};

}  // namespace fieldgate::sparkplug
