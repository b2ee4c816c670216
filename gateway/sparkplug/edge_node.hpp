#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/steady_timer.hpp>

#include <memory>
#include <string>
#include <vector>

#include "gateway/config/config_loader.hpp"
#include "gateway/control/control_service.hpp"
#include "gateway/image/process_image.hpp"
#include "gateway/sparkplug/metric_mapping.hpp"
#include "gateway/sparkplug/mqtt_connection.hpp"
#include "gateway/sparkplug/primary_host_state.hpp"
#include "gateway/sparkplug/session_stats.hpp"
#include "gateway/sparkplug/sparkplug_config.hpp"
#include "gateway/sparkplug/topic_namespace.hpp"

namespace fieldgate::sparkplug {

// The gateway as a Sparkplug B 3.0 edge node: one device per gateway node (device ID = node
// name). Session lifecycle: the NDEATH with this session's bdSeq is the MQTT will; after CONNACK
// (and, with a primary host configured, once its STATE says online) NBIRTH and a DBIRTH for
// every online node; DDEATH/DBIRTH follow each node's online state; DDATA reports changes beyond
// the deadband of the point's type; seq runs 0-255 over NBIRTH, DBIRTH, DDATA, DDEATH.
// NCMD "Node Control/Rebirth" publishes the births again; DCMD goes through the control service, as
// every front door's writes do.
//
// No store-and-forward: while the broker is away nothing is queued, and the births after the
// reconnect carry every current value.
class EdgeNode {
 public:
  EdgeNode(asio::any_io_executor executor, const SparkplugConfig& config);
  ~EdgeNode();

  // The configuration generation in force: on start and after every reload (births follow when
  // the session is up, as the metrics may have changed).
  // Every node is a device. `policies` by node number: what DCMD may change on each (the gateway
  // gives each node the policy of the door that owns it, so a monitor-only node stays so).
  void bind(std::shared_ptr<const LoadedConfig> config, ProcessImage& image,
            std::shared_ptr<ControlService> control, std::vector<WritePolicy> policies);
  void start();
  // NDEATH, then DISCONNECT.
  void stop();

  const SparkplugConfig& config() const { return config_; }
  const SessionStats& stats() const { return stats_; }

 private:
  struct Device {
    std::string id;
    int node_index = 0;
    ModelPtr model;
    std::vector<DeviceMetric> metrics;
    std::vector<MetricValue> published;
    bool born = false;
    CommandState command;
  };
  struct NodeMetric {
    std::string name;
    DataType type;
    MetricValue value;
  };

  uint64_t next_seq();
  MqttConnection::Will next_will();
  std::string death_payload(uint64_t bd_seq) const;
  std::vector<NodeMetric> node_metrics() const;
  void on_connected();
  void on_disconnected();
  void on_message(const std::string& topic, std::string_view payload);
  void on_host_state(std::string_view payload);
  void on_node_command(const Payload& payload);
  void on_device_command(Device& device, const Payload& payload);
  void birth();
  void device_birth(Device& device);
  void device_death(Device& device);
  // with_command: the Command/* metrics go out even unchanged (a new command's result may
  // equal the last one's).
  void scan_device(Device& device, bool include_slow, bool with_command = false);
  void scan_node();
  void schedule_scan();
  bool publish(const std::string& topic, const Payload& payload);

  asio::any_io_executor executor_;
  SparkplugConfig config_;
  TopicNamespace topics_;
  SessionStats stats_;
  MqttConnection connection_;
  PrimaryHostTracker primary_;
  asio::steady_timer scan_timer_;
  SteadyTime next_slow_scan_{};

  std::shared_ptr<const LoadedConfig> loaded_;
  ProcessImage* image_ = nullptr;
  std::shared_ptr<ControlService> control_;
  std::vector<WritePolicy> policies_;  // by node number
  std::vector<Device> devices_;
  std::vector<NodeMetric> node_published_;

  uint64_t bd_seq_ = 0;  // of the CONNECT being attempted, or of the session
  bool session_bd_seq_used_ = false;
  uint8_t seq_ = 0;
  bool born_ = false;
  bool running_ = false;
  // Commands in flight report through this; they find it gone when the edge node is.
  std::shared_ptr<EdgeNode*> self_ = std::make_shared<EdgeNode*>(this);
};

}  // namespace fieldgate::sparkplug
