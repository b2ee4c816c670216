#include "gateway/sparkplug/edge_node.hpp"

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>

#include <algorithm>

#include "gateway/lifecycle/log.hpp"
#include "gateway/sparkplug/command_executor.hpp"

#ifndef FIELDGATE_VERSION
#define FIELDGATE_VERSION "unknown"
#endif

namespace fieldgate::sparkplug {

namespace {

constexpr std::string_view kRebirth = "Node Control/Rebirth";

// Device IDs are topic levels.
std::string device_id_of(const std::string& node_name) {
  std::string id = node_name;
  std::replace_if(
      id.begin(), id.end(), [](char c) { return c == '/' || c == '+' || c == '#'; }, '_');
  return id;
}

}  // namespace

EdgeNode::EdgeNode(asio::any_io_executor executor, const SparkplugConfig& config)
    : executor_(executor),
      config_(config),
      topics_(config.group_id, config.edge_node_id),
      connection_(executor, config,
                  {[this] { return next_will(); }, [this] { on_connected(); },
                   [this] { on_disconnected(); },
                   [this](const std::string& topic, std::string_view payload) {
                     on_message(topic, payload);
                   }},
                  stats_),
      scan_timer_(executor) {}

EdgeNode::~EdgeNode() {
  *self_ = nullptr;
  stop();
}

void EdgeNode::bind(std::shared_ptr<const LoadedConfig> config, ProcessImage& image,
                    std::shared_ptr<ControlService> control, std::vector<WritePolicy> policies) {
  loaded_ = std::move(config);
  image_ = &image;
  control_ = std::move(control);
  policies_ = std::move(policies);
  devices_.clear();
  int node_index = 0;
  for (const auto& bus : loaded_->gateway.buses)
    for (const auto& node : bus.nodes) {
      Device d;
      d.id = device_id_of(node.name);
      d.node_index = node_index++;
      d.model = node.model;
      d.metrics = device_metrics(*d.model, config_);
      devices_.push_back(std::move(d));
    }
  std::sort(devices_.begin(), devices_.end(),
            [](const Device& a, const Device& b) { return a.node_index < b.node_index; });
  if (born_) birth();
}

void EdgeNode::start() {
  running_ = true;
  log::notice("sparkplug: edge node {}/{} for {} device(s), broker {}:{}{}", config_.group_id,
              config_.edge_node_id, devices_.size(), config_.host, config_.port,
              config_.commands_enabled ? ", commands enabled" : "");
  connection_.start();
  schedule_scan();
}

void EdgeNode::stop() {
  if (!running_) return;
  running_ = false;
  scan_timer_.cancel();
  if (connection_.connected()) {
    // A clean DISCONNECT makes the broker drop the will: the death is published first.
    connection_.publish(topics_.node_topic(MessageType::ndeath), death_payload(bd_seq_), 1, false);
    ++stats_.deaths;
  }
  connection_.stop();
  born_ = false;
}

uint64_t EdgeNode::next_seq() {
  const uint64_t s = seq_;
  seq_ = static_cast<uint8_t>(seq_ + 1);  // wraps 255 -> 0
  return s;
}

MqttConnection::Will EdgeNode::next_will() {
  // bdSeq goes up by one from the previous CONNECT that reached the broker; an attempt that
  // never got a session registered no will and keeps the number.
  if (session_bd_seq_used_) {
    bd_seq_ = (bd_seq_ + 1) % 256;
    session_bd_seq_used_ = false;
  }
  stats_.bd_seq = bd_seq_;
  return {topics_.node_topic(MessageType::ndeath), death_payload(bd_seq_)};
}

std::string EdgeNode::death_payload(uint64_t bd_seq) const {
  Payload p = make_payload(now_ms(), std::nullopt);
  add_metric(p, "bdSeq", DataType::uint64, {false, static_cast<int64_t>(bd_seq), {}}, now_ms());
  return encode(p);
}

std::vector<EdgeNode::NodeMetric> EdgeNode::node_metrics() const {
  const auto n = [](uint64_t v) { return MetricValue{false, static_cast<int64_t>(v), {}}; };
  return {
      {"Node Info/Version", DataType::string, {false, 0, FIELDGATE_VERSION}},
      {"Node Info/Devices", DataType::uint32, n(devices_.size())},
      {"Node Info/Commands enabled", DataType::boolean, n(config_.commands_enabled ? 1 : 0)},
      {"Diagnostics/MQTT connects", DataType::uint64, n(stats_.connects)},
      {"Diagnostics/MQTT connection losses", DataType::uint64, n(stats_.connection_losses)},
      {"Diagnostics/Commands received", DataType::uint64, n(stats_.commands_received)},
      {"Diagnostics/Commands rejected", DataType::uint64, n(stats_.commands_rejected)},
      {"Diagnostics/Commands failed", DataType::uint64, n(stats_.commands_failed)},
      {"Diagnostics/Commands unknown", DataType::uint64, n(stats_.commands_unknown)},
      {"Diagnostics/Commands completed", DataType::uint64, n(stats_.commands_completed)},
      {"Diagnostics/Malformed messages", DataType::uint64, n(stats_.malformed_messages)},
  };
}

void EdgeNode::on_connected() {
  session_bd_seq_used_ = true;
  born_ = false;
  // Commands first, so none sent in answer to the births is missed.
  connection_.subscribe(topics_.ncmd_filter(), 1);
  connection_.subscribe(topics_.dcmd_filter(), 1);
  if (config_.primary_host_id) {
    connection_.subscribe(TopicNamespace::state_topic(*config_.primary_host_id), 1);
    if (!primary_.online()) {
      stats_.waiting_for_primary_host = true;
      log::notice("sparkplug: waiting for primary host {} to be online", *config_.primary_host_id);
      return;
    }
  }
  birth();
}

void EdgeNode::on_disconnected() {
  born_ = false;
  stats_.born = false;
  for (auto& d : devices_) d.born = false;
}

bool EdgeNode::publish(const std::string& topic, const Payload& payload) {
  return connection_.publish(topic, encode(payload), 0, false);
}

void EdgeNode::birth() {
  if (!connection_.connected() || !image_) return;
  stats_.waiting_for_primary_host = false;
  seq_ = 0;
  const uint64_t ts = now_ms();
  Payload p = make_payload(ts, next_seq());
  add_metric(p, "bdSeq", DataType::uint64, {false, static_cast<int64_t>(bd_seq_), {}}, ts);
  add_metric(p, kRebirth, DataType::boolean, {false, 0, {}}, ts);
  node_published_ = node_metrics();
  for (const auto& m : node_published_) add_metric(p, m.name, m.type, m.value, ts);
  if (!publish(topics_.node_topic(MessageType::nbirth), p)) return;
  born_ = true;
  stats_.born = true;
  ++stats_.births;
  log::notice("sparkplug: NBIRTH {}/{} bdSeq {}", config_.group_id, config_.edge_node_id, bd_seq_);
  next_slow_scan_ =
      std::chrono::steady_clock::now() +
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(config_.diagnostics_interval);
  for (auto& d : devices_) {
    d.born = false;
    if (image_->node(d.node_index).state == NodeState::online) device_birth(d);
  }
}

void EdgeNode::device_birth(Device& d) {
  const auto now = std::chrono::steady_clock::now();
  const uint64_t ts = now_ms();
  Payload p = make_payload(ts, next_seq());
  d.published.clear();
  for (const auto& m : d.metrics) {
    d.published.push_back(sample(m, *d.model, *image_, d.node_index, d.command, now));
    add_metric(p, m.name, m.type, d.published.back(), ts);
  }
  if (!publish(topics_.device_topic(MessageType::dbirth, d.id), p)) return;
  d.born = true;
  ++stats_.births;
}

void EdgeNode::device_death(Device& d) {
  Payload p = make_payload(now_ms(), next_seq());
  d.born = false;
  if (publish(topics_.device_topic(MessageType::ddeath, d.id), p)) ++stats_.deaths;
}

void EdgeNode::scan_device(Device& d, bool include_slow, bool with_command) {
  if (!born_) return;
  const bool online = image_->node(d.node_index).state == NodeState::online;
  if (online && !d.born) {
    device_birth(d);
    return;
  }
  if (!online && d.born) {
    device_death(d);
    return;
  }
  if (!d.born) return;
  const auto now = std::chrono::steady_clock::now();
  const uint64_t ts = now_ms();
  Payload p = make_payload(ts, std::nullopt);
  for (std::size_t i = 0; i < d.metrics.size(); ++i) {
    if (d.metrics[i].slow && !include_slow) continue;
    const MetricValue v = sample(d.metrics[i], *d.model, *image_, d.node_index, d.command, now);
    const auto source = d.metrics[i].source;
    const bool command = source == DeviceMetric::Source::command_metric ||
                         source == DeviceMetric::Source::command_result ||
                         source == DeviceMetric::Source::command_detail ||
                         source == DeviceMetric::Source::command_sequence;
    if (!(with_command && command) && !changed(d.metrics[i], d.published[i], v)) continue;
    d.published[i] = v;
    add_metric(p, d.metrics[i].name, d.metrics[i].type, v, ts);
  }
  if (p.metrics_size() == 0) return;
  p.set_seq(next_seq());
  publish(topics_.device_topic(MessageType::ddata, d.id), p);
}

void EdgeNode::scan_node() {
  if (!born_) return;
  const uint64_t ts = now_ms();
  Payload p = make_payload(ts, std::nullopt);
  auto current = node_metrics();
  for (std::size_t i = 0; i < current.size() && i < node_published_.size(); ++i)
    if (current[i].value != node_published_[i].value)
      add_metric(p, current[i].name, current[i].type, current[i].value, ts);
  node_published_ = std::move(current);
  if (p.metrics_size() == 0) return;
  p.set_seq(next_seq());
  publish(topics_.node_topic(MessageType::ndata), p);
}

void EdgeNode::schedule_scan() {
  scan_timer_.expires_after(config_.scan_interval);
  scan_timer_.async_wait([this](const boost::system::error_code& ec) {
    if (ec || !running_) return;
    const auto now = std::chrono::steady_clock::now();
    const bool slow = now >= next_slow_scan_;
    if (slow)
      next_slow_scan_ = now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                  config_.diagnostics_interval);
    for (auto& d : devices_) scan_device(d, slow);
    if (slow) scan_node();
    schedule_scan();
  });
}

void EdgeNode::on_message(const std::string& topic, std::string_view payload) {
  if (config_.primary_host_id && topic == TopicNamespace::state_topic(*config_.primary_host_id)) {
    on_host_state(payload);
    return;
  }
  const auto command = topics_.parse_command(topic);
  if (!command) return;
  auto decoded = decode(payload);
  if (!decoded) {
    ++stats_.malformed_messages;
    log::warning("sparkplug: {} on {}: not a Sparkplug B payload", to_string(command->type), topic);
    return;
  }
  if (command->type == MessageType::ncmd) {
    on_node_command(*decoded);
    return;
  }
  for (auto& d : devices_) {
    if (d.id == command->device_id) {
      on_device_command(d, *decoded);
      return;
    }
  }
  ++stats_.malformed_messages;
  log::warning("sparkplug: DCMD for unknown device '{}'", command->device_id);
}

void EdgeNode::on_host_state(std::string_view payload) {
  const auto state = parse_host_state(payload);
  if (!state) {
    ++stats_.malformed_messages;
    log::warning("sparkplug: STATE of {} is not {{\"online\": bool, \"timestamp\": ms}}",
                 *config_.primary_host_id);
    return;
  }
  if (!primary_.update(*state)) return;  // older than the state in force
  if (state->online) {
    log::notice("sparkplug: primary host {} is online", *config_.primary_host_id);
    if (!born_ && connection_.connected()) birth();
    return;
  }
  log::notice("sparkplug: primary host {} is offline", *config_.primary_host_id);
  if (born_) {
    // Sparkplug 3.0: the edge node dies and reconnects, then waits for the host to be online.
    connection_.publish(topics_.node_topic(MessageType::ndeath), death_payload(bd_seq_), 1, false);
    ++stats_.deaths;
    on_disconnected();
    connection_.restart();
  } else {
    stats_.waiting_for_primary_host = true;
  }
}

void EdgeNode::on_node_command(const Payload& payload) {
  for (const auto& m : payload.metrics()) {
    if (m.name() == kRebirth) {
      if (integer_value(m).value_or(0) != 1) continue;
      ++stats_.rebirth_requests;
      log::notice("sparkplug: rebirth requested");
      if (connection_.connected() && (!config_.primary_host_id || primary_.online())) birth();
    } else {
      log::warning("sparkplug: NCMD metric '{}' is not supported", m.name());
    }
  }
}

void EdgeNode::on_device_command(Device& d, const Payload& payload) {
  struct Item {
    DeviceMetric metric;
    Metric value;
  };
  std::vector<Item> items;
  for (const auto& m : payload.metrics()) {
    ++stats_.commands_received;
    const auto it = std::find_if(d.metrics.begin(), d.metrics.end(),
                                 [&](const DeviceMetric& dm) { return dm.name == m.name(); });
    std::string refusal;
    if (!config_.commands_enabled)
      refusal = "commands are disabled (sparkplug commands_enabled: false)";
    else if (it == d.metrics.end())
      refusal = "no such metric";
    else if (!it->writable)
      refusal = "the metric is not writable";
    if (!refusal.empty()) {
      ++stats_.commands_rejected;
      log::warning("sparkplug: DCMD {} {} rejected: {}", d.id, m.name(), refusal);
      d.command = {m.name(), "rejected", refusal, d.command.sequence + 1};
      scan_device(d, false, true);
      continue;
    }
    items.push_back({*it, m});
  }
  if (items.empty()) return;
  CommandTarget target{loaded_, control_, image_, d.node_index,
                       policies_.at(static_cast<std::size_t>(d.node_index))};
  const std::string device_id = d.id;
  std::weak_ptr<EdgeNode*> self = self_;
  // One command after the other, in the order of the payload (a target before its move).
  auto run = [](CommandTarget target, std::vector<Item> items, std::string device_id,
                std::weak_ptr<EdgeNode*> self) -> asio::awaitable<void> {
    for (auto& item : items) {
      const std::string name = item.metric.name;
      uint64_t sequence = 0;
      CommandReport report = [&self, &device_id, &name, &sequence](const CommandOutcome& o) {
        const auto alive = self.lock();
        if (!alive || !*alive) return;
        EdgeNode& node = **alive;
        auto& stats = node.stats_;
        if (o.final) {
          if (o.result == "rejected")
            ++stats.commands_rejected;
          else if (o.result == "unknown")
            ++stats.commands_unknown;
          else if (o.result == "failed" || o.result == "error" || o.result == "superseded")
            ++stats.commands_failed;
          else
            ++stats.commands_completed;
        }
        log::notice("sparkplug: DCMD {} {}: {} ({})", device_id, name, o.result, o.detail);
        for (auto& dev : node.devices_) {
          if (dev.id != device_id) continue;
          if (sequence == 0) sequence = dev.command.sequence + 1;
          dev.command = {name, o.result, o.detail, sequence};
          node.scan_device(dev, false, true);
        }
      };
      CommandTarget t = target;
      DeviceMetric metric = item.metric;
      Metric value = item.value;
      co_await execute_command(t, metric, value, report);
    }
  };
  asio::co_spawn(executor_, run(target, std::move(items), device_id, self), asio::detached);
}

}  // namespace fieldgate::sparkplug
