#include "gateway/sparkplug/mqtt_connection.hpp"

#include <mosquitto.h>
#include <sys/ioctl.h>
#include <unistd.h>
#include <boost/asio/post.hpp>

#include <algorithm>
#include <mutex>

#include "gateway/lifecycle/log.hpp"

namespace fieldgate::sparkplug {

namespace {
std::once_flag library_once;

// libmosquitto says why TLS failed (OpenSSL's error, e.g. "certificate verify failed") only in
// its log; its return code is a bare MOSQ_ERR_TLS.
void on_library_log(mosquitto*, void*, int level, const char* text) {
  if (level & (MOSQ_LOG_ERR | MOSQ_LOG_WARNING)) log::warning("sparkplug: libmosquitto: {}", text);
}
}  // namespace

MqttConnection::MqttConnection(asio::any_io_executor executor, const SparkplugConfig& config,
                               Handlers handlers, SessionStats& stats)
    : executor_(executor),
      config_(config),
      handlers_(std::move(handlers)),
      stats_(stats),
      resolver_(executor),
      socket_(executor),
      misc_timer_(executor),
      reconnect_timer_(executor),
      backoff_(config.reconnect_min) {
  std::call_once(library_once, [] { mosquitto_lib_init(); });
  mosq_ = mosquitto_new(config_.effective_client_id().c_str(), true, this);
  if (!mosq_) throw std::runtime_error("sparkplug: mosquitto_new failed");
  mosquitto_int_option(mosq_, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
  mosquitto_connect_callback_set(mosq_, &MqttConnection::on_connect);
  mosquitto_message_callback_set(mosq_, &MqttConnection::on_message);
  mosquitto_log_callback_set(mosq_, &on_library_log);
  if (!config_.username.empty())
    mosquitto_username_pw_set(mosq_, config_.username.c_str(),
                              config_.password.empty() ? nullptr : config_.password.c_str());
  if (config_.tls) {
    int rc = MOSQ_ERR_SUCCESS;
    if (config_.ca_file.empty()) {
      rc = mosquitto_int_option(mosq_, MOSQ_OPT_TLS_USE_OS_CERTS, 1);
    } else {
      rc =
          mosquitto_tls_set(mosq_, config_.ca_file.c_str(), nullptr,
                            config_.cert_file.empty() ? nullptr : config_.cert_file.c_str(),
                            config_.key_file.empty() ? nullptr : config_.key_file.c_str(), nullptr);
    }
    if (rc != MOSQ_ERR_SUCCESS)
      log::error("sparkplug: TLS set-up failed: {}", mosquitto_strerror(rc));
  }
}

MqttConnection::~MqttConnection() {
  stop();
  mosquitto_destroy(mosq_);
}

void MqttConnection::start() {
  running_ = true;
  resolve_and_connect();
}

void MqttConnection::stop() {
  if (!running_) return;
  running_ = false;
  reconnect_timer_.cancel();
  misc_timer_.cancel();
  resolver_.cancel();
  if (fd_ >= 0) {
    mosquitto_disconnect(mosq_);
    // The DISCONNECT is written at once when the socket takes it; nothing waits for more.
    mosquitto_loop_write(mosq_, 1);
  }
  ++*epoch_;
  boost::system::error_code ignored;
  socket_.close(ignored);
  fd_ = -1;
  connected_ = false;
  stats_.connected = false;
}

void MqttConnection::restart() {
  if (!running_) return;
  if (fd_ >= 0) {
    mosquitto_disconnect(mosq_);
    mosquitto_loop_write(mosq_, 1);
  }
  lost("restart asked for");
}

void MqttConnection::resolve_and_connect() {
  if (!running_) return;
  resolver_.async_resolve(
      config_.host, std::to_string(config_.port),
      [this, epoch = mark_epoch()](const boost::system::error_code& ec,
                                   asio::ip::tcp::resolver::results_type results) {
        if (!epoch.current() || !running_) return;
        if (ec || results.empty()) {
          ++stats_.connect_failures;
          log::warning("sparkplug: cannot resolve broker {}: {}", config_.host, ec.message());
          schedule_reconnect();
          return;
        }
        // With TLS the certificate is checked against the name, so libmosquitto gets the name
        // and looks it up again, blocking the io_context. Resolved here first, a DNS that does
        // not answer (the usual outage) never gets there; a slow one still does.
        connect_to(config_.tls ? config_.host : results.begin()->endpoint().address().to_string());
      });
}

void MqttConnection::connect_to(const std::string& address) {
  if (handlers_.next_will) {
    const Will will = handlers_.next_will();
    mosquitto_will_set(mosq_, will.topic.c_str(), static_cast<int>(will.payload.size()),
                       will.payload.data(), 1, false);
  }
  const int keepalive = static_cast<int>(std::max<int64_t>(
      5, std::chrono::duration_cast<std::chrono::seconds>(config_.keepalive).count()));
  const int rc = mosquitto_connect_async(mosq_, address.c_str(), config_.port, keepalive);
  if (rc != MOSQ_ERR_SUCCESS) {
    ++stats_.connect_failures;
    log::warning(
        "sparkplug: cannot connect to {}:{}: {}", config_.host, config_.port,
        rc == MOSQ_ERR_ERRNO ? std::string(strerror(errno)) : std::string(mosquitto_strerror(rc)));
    schedule_reconnect();
    return;
  }
  watch_socket();
}

void MqttConnection::watch_socket() {
  const int fd = mosquitto_socket(mosq_);
  if (fd < 0) {
    lost("no socket");
    return;
  }
  boost::system::error_code ignored;
  socket_.close(ignored);
  ++*epoch_;
  fd_ = fd;
  // A duplicate: libmosquitto closes its own descriptor whenever it likes.
  socket_.assign(::dup(fd));
  writing_ = false;
  wait_readable();
  wait_writable();
  tick();
}

void MqttConnection::wait_readable() {
  socket_.async_wait(asio::posix::stream_descriptor::wait_read,
                     [this, epoch = mark_epoch()](const boost::system::error_code& ec) {
                       if (ec || !epoch.current()) return;
                       // One packet per call: packets already in the socket buffer raise
                       // no new readiness, so they are read now.
                       for (int n = 0; n < 64; ++n) {
                         check(mosquitto_loop_read(mosq_, 1), "read");
                         if (!epoch.current()) return;
                         int pending = 0;
                         if (::ioctl(fd_, FIONREAD, &pending) != 0 || pending <= 0) break;
                       }
                       wait_readable();
                       wait_writable();
                     });
}

void MqttConnection::wait_writable() {
  if (writing_ || !mosquitto_want_write(mosq_)) return;
  writing_ = true;
  socket_.async_wait(asio::posix::stream_descriptor::wait_write,
                     [this, epoch = mark_epoch()](const boost::system::error_code& ec) {
                       if (ec || !epoch.current()) return;
                       writing_ = false;
                       check(mosquitto_loop_write(mosq_, 1), "write");
                       if (!epoch.current()) return;
                       wait_writable();
                     });
}

void MqttConnection::tick() {
  misc_timer_.expires_after(std::chrono::milliseconds(500));
  misc_timer_.async_wait([this, epoch = mark_epoch()](const boost::system::error_code& ec) {
    if (ec || !epoch.current()) return;
    // Keepalive: PINGREQ when due, and the session's end when PINGRESP stays away.
    check(mosquitto_loop_misc(mosq_), "keepalive");
    if (!epoch.current()) return;
    wait_writable();
    tick();
  });
}

void MqttConnection::check(int rc, const char* what) {
  if (rc == MOSQ_ERR_SUCCESS && mosquitto_socket(mosq_) == fd_) return;
  std::string why = rc == MOSQ_ERR_SUCCESS ? "socket closed"
                    : rc == MOSQ_ERR_ERRNO ? std::string(strerror(errno))
                                           : std::string(mosquitto_strerror(rc));
  lost(fmt::format("{}: {}", what, why));
}

void MqttConnection::lost(const std::string& why) {
  ++*epoch_;
  boost::system::error_code ignored;
  socket_.close(ignored);
  misc_timer_.cancel();
  fd_ = -1;
  const bool was_connected = connected_;
  connected_ = false;
  stats_.connected = false;
  if (was_connected) {
    ++stats_.connection_losses;
    log::warning("sparkplug: session with {}:{} ended ({})", config_.host, config_.port, why);
    if (handlers_.disconnected) handlers_.disconnected();
  } else {
    ++stats_.connect_failures;
    log::warning("sparkplug: cannot reach broker {}:{} ({})", config_.host, config_.port, why);
  }
  schedule_reconnect();
}

void MqttConnection::schedule_reconnect() {
  if (!running_) return;
  const auto wait = backoff_;
  backoff_ = std::min(backoff_ * 2, config_.reconnect_max);
  log::info("sparkplug: reconnecting in {} ms",
            std::chrono::duration_cast<std::chrono::milliseconds>(wait).count());
  reconnect_timer_.expires_after(wait);
  reconnect_timer_.async_wait([this](const boost::system::error_code& ec) {
    if (!ec) resolve_and_connect();
  });
}

void MqttConnection::on_connect(mosquitto*, void* self, int rc) {
  auto* c = static_cast<MqttConnection*>(self);
  if (rc != 0) {
    log::warning("sparkplug: broker refused the connection: {}", mosquitto_connack_string(rc));
    return;  // the broker closes the socket: check() sees it
  }
  c->connected_ = true;
  c->stats_.connected = true;
  ++c->stats_.connects;
  c->backoff_ = c->config_.reconnect_min;
  log::notice("sparkplug: connected to {}:{} as {}", c->config_.host, c->config_.port,
              c->config_.effective_client_id());
  c->deliver([c] {
    if (c->handlers_.connected) c->handlers_.connected();
  });
}

// libmosquitto calls back with its callback mutex held, and a DISCONNECT written from inside a
// callback takes that mutex again (a deadlock): handlers run after the callback has returned.
void MqttConnection::deliver(std::function<void()> handler) {
  asio::post(executor_, [epoch = mark_epoch(), handler = std::move(handler)] {
    if (epoch.current()) handler();
  });
}

void MqttConnection::on_message(mosquitto*, void* self, const mosquitto_message* message) {
  auto* c = static_cast<MqttConnection*>(self);
  if (!c->handlers_.message) return;
  std::string topic = message->topic;
  std::string payload(static_cast<const char*>(message->payload),
                      static_cast<std::size_t>(message->payloadlen));
  c->deliver([c, topic = std::move(topic), payload = std::move(payload)] {
    c->handlers_.message(topic, payload);
  });
}

bool MqttConnection::publish(const std::string& topic, const std::string& payload, int qos,
                             bool retain) {
  if (!connected_) {
    ++stats_.publish_failures;
    return false;
  }
  const int rc = mosquitto_publish(mosq_, nullptr, topic.c_str(), static_cast<int>(payload.size()),
                                   payload.data(), qos, retain);
  if (rc != MOSQ_ERR_SUCCESS) {
    ++stats_.publish_failures;
    log::warning("sparkplug: publish on {} failed: {}", topic, mosquitto_strerror(rc));
    return false;
  }
  ++stats_.messages_published;
  stats_.bytes_published += payload.size();
  wait_writable();
  return true;
}

bool MqttConnection::subscribe(const std::string& filter, int qos) {
  if (!connected_) return false;
  const int rc = mosquitto_subscribe(mosq_, nullptr, filter.c_str(), qos);
  if (rc != MOSQ_ERR_SUCCESS) {
    log::warning("sparkplug: subscribe to {} failed: {}", filter, mosquitto_strerror(rc));
    return false;
  }
  wait_writable();
  return true;
}

}  // namespace fieldgate::sparkplug
