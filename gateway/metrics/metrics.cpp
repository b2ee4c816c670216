#include "gateway/metrics/metrics.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "gateway/gateway.hpp"
#include "gateway/image/point_freshness.hpp"
#include "gateway/metrics/process_metrics.hpp"
#include "gateway/sparkplug/session_stats.hpp"

#ifndef FIELDGATE_VERSION
#define FIELDGATE_VERSION "unknown"
#endif

namespace fieldgate {

namespace {

// Label values: backslash, double quote and newline escaped as the format requires.
std::string label(std::string_view value) {
  std::string out;
  for (const char c : value) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

class Writer {
 public:
  void family(std::string_view name, std::string_view type, std::string_view help) {
    text_ += fmt::format("# HELP {} {}\n# TYPE {} {}\n", name, help, name, type);
  }
  void sample(std::string_view name, std::string_view labels, double value) {
    text_ += fmt::format("{}{}{}{} {}\n", name, labels.empty() ? "" : "{", labels,
                         labels.empty() ? "" : "}", value);
  }
  std::string text() && { return std::move(text_); }

 private:
  std::string text_;
};

}  // namespace

std::string render_metrics(const Gateway& gateway) {
  Writer w;
  const auto now = std::chrono::steady_clock::now();
  w.family("fieldgate_build_info", "gauge", "Build information.");
  w.sample("fieldgate_build_info", fmt::format("version=\"{}\"", FIELDGATE_VERSION), 1);

  const auto& buses = gateway.buses();
  struct BusCounter {
    const char* name;
    const char* help;
    uint64_t BusCounters::*field;
  };
  const BusCounter counters[] = {
      {"fieldgate_bus_transactions_total", "Transactions on the bus.", &BusCounters::transactions},
      {"fieldgate_bus_timeouts_total", "Transactions that timed out.", &BusCounters::timeouts},
      {"fieldgate_bus_unreachable_total",
       "Transactions a forwarding device answered 'node unreachable' (Copley e 32).",
       &BusCounters::unreachable},
      {"fieldgate_bus_errors_total", "Device error and garbled replies.", &BusCounters::errors},
      {"fieldgate_bus_retries_total", "Poll retries.", &BusCounters::retries},
      {"fieldgate_bus_commands_total", "Commands from Modbus writes.", &BusCounters::commands},
      {"fieldgate_bus_resyncs_total",
       "Guard periods waited after a timeout, garbled reply or stray bytes.",
       &BusCounters::resyncs},
      {"fieldgate_bus_resync_bytes_total", "Late or stray bytes drained while resyncing.",
       &BusCounters::resync_bytes},
      {"fieldgate_bus_alignment_proofs_total",
       "Exchanges run to prove the line in step after a failure.", &BusCounters::alignment_proofs},
      {"fieldgate_bus_alignment_failures_total",
       "Proofs of alignment that failed (no reply is trusted until one passes).",
       &BusCounters::alignment_failures},
      {"fieldgate_bus_stray_replies_total",
       "Late or stray replies drained while proving the line in step.",
       &BusCounters::stray_replies},
      {"fieldgate_bus_sent_ahead_total",
       "Polls whose request went out the moment the reply before it was accepted.",
       &BusCounters::sent_ahead},
      {"fieldgate_bus_sent_ahead_lost_total",
       "Requests sent ahead that their exchange did not take over (reply owed, line proven again).",
       &BusCounters::sent_ahead_lost},
      {"fieldgate_bus_reconnects_total", "Times the link was opened.", &BusCounters::reconnects},
      {"fieldgate_bus_sent_bytes_total", "Bytes written to the link.", &BusCounters::bytes_sent},
      {"fieldgate_bus_received_bytes_total", "Bytes read from the link.",
       &BusCounters::bytes_received},
  };
  for (const auto& c : counters) {
    w.family(c.name, "counter", c.help);
    for (const auto& bus : buses)
      w.sample(c.name, fmt::format("bus=\"{}\"", label(bus->config().name)),
               static_cast<double>(bus->counters().*c.field));
  }
  // Families and samples only where there are CAN buses.
  struct CanCounter {
    const char* name;
    const char* help;
    uint64_t CanCounters::*field;
  };
  const CanCounter can_counters[] = {
      {"fieldgate_bus_can_frames_sent_total", "CAN frames sent.", &CanCounters::frames_sent},
      {"fieldgate_bus_can_frames_received_total", "CAN frames received.",
       &CanCounters::frames_received},
      {"fieldgate_bus_can_error_frames_total", "CAN error frames.", &CanCounters::error_frames},
      {"fieldgate_bus_can_bus_off_total", "CAN bus-off events.", &CanCounters::bus_off},
      {"fieldgate_bus_can_rx_dropped_total", "CAN frames the kernel dropped on receive.",
       &CanCounters::rx_dropped},
      {"fieldgate_bus_can_tx_dropped_total", "CAN frames that could not be sent.",
       &CanCounters::tx_dropped},
  };
  const bool any_can = std::any_of(buses.begin(), buses.end(),
                                   [](const auto& bus) { return bus->can_counters() != nullptr; });
  for (const auto& c : can_counters) {
    if (!any_can) break;
    w.family(c.name, "counter", c.help);
    for (const auto& bus : buses)
      if (const auto* can = bus->can_counters())
        w.sample(c.name, fmt::format("bus=\"{}\"", label(bus->config().name)),
                 static_cast<double>(can->*c.field));
  }
  w.family("fieldgate_bus_up", "gauge", "1 while the bus's link is open.");
  for (const auto& bus : buses)
    w.sample("fieldgate_bus_up", fmt::format("bus=\"{}\"", label(bus->config().name)),
             bus->counters().link_up ? 1 : 0);
  w.family("fieldgate_bus_transaction_seconds", "histogram", "Transaction latency.");
  for (const auto& bus : buses) {
    const auto& c = bus->counters();
    const std::string b = label(bus->config().name);
    uint64_t cumulative = 0;
    for (std::size_t i = 0; i < std::size(kLatencyBuckets); ++i) {
      cumulative += c.latency_counts[i];
      w.sample("fieldgate_bus_transaction_seconds_bucket",
               fmt::format("bus=\"{}\",le=\"{}\"", b, kLatencyBuckets[i]),
               static_cast<double>(cumulative));
    }
    cumulative += c.latency_counts.back();
    w.sample("fieldgate_bus_transaction_seconds_bucket", fmt::format("bus=\"{}\",le=\"+Inf\"", b),
             static_cast<double>(cumulative));
    w.sample("fieldgate_bus_transaction_seconds_sum", fmt::format("bus=\"{}\"", b), c.latency_sum);
    w.sample("fieldgate_bus_transaction_seconds_count", fmt::format("bus=\"{}\"", b),
             static_cast<double>(cumulative));
  }

  // Nodes in the gateway's order, labelled with bus, node name and unit ID.
  const auto& config = gateway.config();
  std::vector<std::string> node_labels;
  for (const auto& bus : config.gateway.buses)
    for (const auto& node : bus.nodes)
      node_labels.push_back(fmt::format("bus=\"{}\",node=\"{}\",unit=\"{}\",listener=\"{}\"",
                                        label(bus.name), label(node.name), node.unit_id,
                                        label(config.gateway.listener_name(node.listener))));
  const auto& image = gateway.image();
  w.family("fieldgate_node_online", "gauge", "1 while the node answers.");
  for (std::size_t i = 0; i < node_labels.size(); ++i)
    w.sample("fieldgate_node_online", node_labels[i],
             image.node(static_cast<int>(i)).state == NodeState::online ? 1 : 0);
  w.family("fieldgate_node_last_good_poll_age_seconds", "gauge",
           "Seconds since the last good reply (absent before the first).");
  for (std::size_t i = 0; i < node_labels.size(); ++i) {
    const auto& c = image.node(static_cast<int>(i)).counters;
    if (c.ever_good)
      w.sample("fieldgate_node_last_good_poll_age_seconds", node_labels[i],
               std::chrono::duration<double>(now - c.last_good).count());
  }
  w.family("fieldgate_node_stale_points", "gauge",
           "Points whose value is stale: its last polls failed, or it is older than its bound.");
  {
    std::size_t i = 0;
    for (const auto& bus : config.gateway.buses)
      for (const auto& node : bus.nodes) {
        const auto& n = image.node(static_cast<int>(i));
        std::size_t stale = 0;
        for (std::size_t p = 0; p < n.points.size(); ++p)
          if (n.points[p].valid && !point_is_fresh(n, *node.model, p, now)) ++stale;
        w.sample("fieldgate_node_stale_points", node_labels[i], static_cast<double>(stale));
        ++i;
      }
  }
  struct NodeCounter {
    const char* name;
    const char* help;
    uint64_t NodeCounters::*field;
  };
  const NodeCounter node_counters[] = {
      {"fieldgate_node_transactions_total", "Transactions with the node.",
       &NodeCounters::transactions},
      {"fieldgate_node_timeouts_total", "Transactions that timed out.", &NodeCounters::timeouts},
      {"fieldgate_node_unreachable_total",
       "Transactions a forwarding device reported the node unreachable for (Copley e 32).",
       &NodeCounters::unreachable},
      {"fieldgate_node_errors_total", "Device errors and garbled replies.", &NodeCounters::errors},
      {"fieldgate_node_failed_polls_total",
       "Polls that fed no value (timeout, garbled, refused, unreachable), probes aside.",
       &NodeCounters::failed_polls},
  };
  for (const auto& c : node_counters) {
    w.family(c.name, "counter", c.help);
    for (std::size_t i = 0; i < node_labels.size(); ++i)
      w.sample(c.name, node_labels[i],
               static_cast<double>(image.node(static_cast<int>(i)).counters.*c.field));
  }

  // Per listener; each has its own clients, allow list and unit-ID space.
  struct ListenerStats {
    std::string label;
    const modbus::ModbusTcpServerStats* stats;
  };
  std::vector<ListenerStats> listeners;
  for (const auto& l : gateway.listeners())
    if (l.server)
      listeners.push_back({fmt::format("listener=\"{}\"", label(l.name)), &l.server->stats()});
  w.family("fieldgate_modbus_requests_total", "counter", "Modbus requests by function code.");
  for (const auto& [l, stats] : listeners)
    for (std::size_t f = 0; f < stats->functions.size(); ++f)
      if (stats->functions[f].requests > 0)
        w.sample("fieldgate_modbus_requests_total", fmt::format("{},function=\"{}\"", l, f),
                 static_cast<double>(stats->functions[f].requests));
  w.family("fieldgate_modbus_exceptions_total", "counter",
           "Modbus exception responses by function code and exception code (code 0: other).");
  for (const auto& [l, stats] : listeners)
    for (std::size_t f = 0; f < stats->functions.size(); ++f)
      for (std::size_t code = 0; code < stats->functions[f].exception_codes.size(); ++code)
        if (stats->functions[f].exception_codes[code] > 0)
          w.sample("fieldgate_modbus_exceptions_total",
                   fmt::format("{},function=\"{}\",code=\"{}\"", l, f, code),
                   static_cast<double>(stats->functions[f].exception_codes[code]));
  w.family("fieldgate_modbus_clients", "gauge", "Modbus clients connected now.");
  for (const auto& [l, stats] : listeners)
    w.sample("fieldgate_modbus_clients", l, static_cast<double>(stats->clients_connected));
  w.family("fieldgate_modbus_clients_refused_total", "counter",
           "Connections closed at once, by the rule that refused them (docs/modbus-tcp.md).");
  for (const auto& [l, stats] : listeners) {
    const auto& r = stats->refused;
    for (const auto& [reason, count] :
         {std::pair{"max_clients", r.max_clients}, std::pair{"per_address", r.per_address},
          std::pair{"connect_rate_per_address", r.rate_per_address},
          std::pair{"connect_rate", r.rate}, std::pair{"no_idle_client", r.no_idle_client},
          std::pair{"allow_list", stats->clients_denied}})
      w.sample("fieldgate_modbus_clients_refused_total", fmt::format("{},reason=\"{}\"", l, reason),
               static_cast<double>(count));
  }
  w.family("fieldgate_modbus_clients_evicted_total", "counter",
           "Connections closed to make room for a new one (when_full: evict_idle), by the rule: "
           "never_spoke (no complete request), overdue (silent beyond its own polling rhythm).");
  for (const auto& [l, stats] : listeners) {
    w.sample("fieldgate_modbus_clients_evicted_total", l + ",reason=\"never_spoke\"",
             static_cast<double>(stats->evicted.never_spoke));
    w.sample("fieldgate_modbus_clients_evicted_total", l + ",reason=\"overdue\"",
             static_cast<double>(stats->evicted.overdue));
  }
  // The metrics and console HTTP servers, whichever are enabled (counts carried over restarts).
  const std::pair<const char*, HttpServerCounts> http[] = {
      {"metrics", gateway.metrics_http_counts()}, {"console", gateway.console_http_counts()}};
  struct HttpCounter {
    const char* name;
    const char* help;
    uint64_t HttpServerCounts::*field;
  };
  const HttpCounter http_counters[] = {
      {"fieldgate_http_connections_refused_total",
       "HTTP connections closed at once: every slot held, none to evict.",
       &HttpServerCounts::refused},
      {"fieldgate_http_connections_evicted_total",
       "HTTP connections closed before their request had come, to make room for a new one.",
       &HttpServerCounts::evicted},
      {"fieldgate_http_denied_total",
       "Denied by the allow list (metrics: connections closed unanswered) or, on the console, "
       "requests answered 403 (address or token).",
       &HttpServerCounts::denied},
      {"fieldgate_http_bad_requests_total",
       "HTTP requests that could not be parsed, answered 400, 413 or 431.",
       &HttpServerCounts::bad_requests},
  };
  for (const auto& c : http_counters) {
    w.family(c.name, "counter", c.help);
    for (const auto& [server, counts] : http)
      w.sample(c.name, fmt::format("server=\"{}\"", server), static_cast<double>(counts.*c.field));
  }
  if (const auto* rtu = gateway.rtu_server()) {
    const auto& r = rtu->stats();
    const std::string port = fmt::format("port=\"{}\"", label(rtu->options().serial.device));
    w.family("fieldgate_modbus_rtu_up", "gauge", "1 while the Modbus RTU port is open.");
    w.sample("fieldgate_modbus_rtu_up", port, r.link_up ? 1 : 0);
    struct RtuCounter {
      const char* name;
      const char* help;
      uint64_t modbus::ModbusRtuServerStats::*field;
    };
    const RtuCounter rtu_counters[] = {
        {"fieldgate_modbus_rtu_frames_total", "Good frames for a unit served on the RTU port.",
         &modbus::ModbusRtuServerStats::frames_ok},
        {"fieldgate_modbus_rtu_crc_errors_total", "Frames dropped for a bad CRC.",
         &modbus::ModbusRtuServerStats::crc_errors},
        {"fieldgate_modbus_rtu_framing_errors_total",
         "Frames dropped as too short, too long or truncated.",
         &modbus::ModbusRtuServerStats::framing_errors},
        {"fieldgate_modbus_rtu_other_unit_frames_total",
         "Good frames for unit IDs not served here (other slaves on the line).",
         &modbus::ModbusRtuServerStats::other_units},
        {"fieldgate_modbus_rtu_broadcasts_accepted_total", "Broadcast stops carried out.",
         &modbus::ModbusRtuServerStats::broadcasts_accepted},
        {"fieldgate_modbus_rtu_broadcasts_dropped_total",
         "Broadcasts dropped: anything but the configured stop.",
         &modbus::ModbusRtuServerStats::broadcasts_dropped},
        {"fieldgate_modbus_rtu_broadcast_write_failures_total",
         "Writes of a broadcast stop that a unit refused or did not confirm.",
         &modbus::ModbusRtuServerStats::broadcast_write_failures},
        {"fieldgate_modbus_rtu_acknowledged_total",
         "Slow confirmed writes answered with exception 0x05 before the master's timeout.",
         &modbus::ModbusRtuServerStats::acknowledged},
        {"fieldgate_modbus_rtu_answers_dropped_total",
         "Answers ready after the master had moved on or given up (not sent).",
         &modbus::ModbusRtuServerStats::answers_dropped},
        {"fieldgate_modbus_rtu_retries_joined_total",
         "Repeated writes attached to the same write still running.",
         &modbus::ModbusRtuServerStats::retries_joined},
        {"fieldgate_modbus_rtu_received_bytes_total", "Bytes read from the RTU port.",
         &modbus::ModbusRtuServerStats::bytes_received},
        {"fieldgate_modbus_rtu_sent_bytes_total", "Bytes written to the RTU port.",
         &modbus::ModbusRtuServerStats::bytes_sent},
        {"fieldgate_modbus_rtu_opens_total", "Times the RTU port was opened.",
         &modbus::ModbusRtuServerStats::opens},
    };
    for (const auto& c : rtu_counters) {
      w.family(c.name, "counter", c.help);
      w.sample(c.name, port, static_cast<double>(r.*c.field));
    }
    w.family("fieldgate_modbus_rtu_requests_total", "counter",
             "Modbus RTU requests by function code.");
    for (std::size_t f = 0; f < r.functions.size(); ++f)
      if (r.functions[f].requests > 0)
        w.sample("fieldgate_modbus_rtu_requests_total", fmt::format("{},function=\"{}\"", port, f),
                 static_cast<double>(r.functions[f].requests));
    w.family("fieldgate_modbus_rtu_exceptions_total", "counter",
             "Modbus RTU exception responses by exception code.");
    for (std::size_t code = 0; code < r.exceptions_by_code.size(); ++code)
      if (r.exceptions_by_code[code] > 0)
        w.sample("fieldgate_modbus_rtu_exceptions_total", fmt::format("{},code=\"{}\"", port, code),
                 static_cast<double>(r.exceptions_by_code[code]));
  }

  if (const auto* sp = gateway.sparkplug_stats()) {
    w.family("fieldgate_sparkplug_connected", "gauge", "1 while the MQTT session is up.");
    w.sample("fieldgate_sparkplug_connected", "", sp->connected ? 1 : 0);
    w.family("fieldgate_sparkplug_born", "gauge", "1 once NBIRTH was published in this session.");
    w.sample("fieldgate_sparkplug_born", "", sp->born ? 1 : 0);
    w.family("fieldgate_sparkplug_waiting_for_primary_host", "gauge",
             "1 while the session waits for the primary host's STATE online.");
    w.sample("fieldgate_sparkplug_waiting_for_primary_host", "",
             sp->waiting_for_primary_host ? 1 : 0);
    w.family("fieldgate_sparkplug_bdseq", "gauge", "bdSeq of the current session.");
    w.sample("fieldgate_sparkplug_bdseq", "", static_cast<double>(sp->bd_seq));
    struct SessionCounter {
      const char* name;
      const char* help;
      uint64_t sparkplug::SessionStats::*field;
    };
    const SessionCounter session_counters[] = {
        {"fieldgate_sparkplug_connects_total", "MQTT sessions established.",
         &sparkplug::SessionStats::connects},
        {"fieldgate_sparkplug_connect_failures_total", "Connection attempts without a session.",
         &sparkplug::SessionStats::connect_failures},
        {"fieldgate_sparkplug_connection_losses_total", "Sessions that ended unasked.",
         &sparkplug::SessionStats::connection_losses},
        {"fieldgate_sparkplug_messages_published_total", "MQTT messages published.",
         &sparkplug::SessionStats::messages_published},
        {"fieldgate_sparkplug_published_bytes_total", "Payload bytes published.",
         &sparkplug::SessionStats::bytes_published},
        {"fieldgate_sparkplug_publish_failures_total", "Publishes that failed or found no session.",
         &sparkplug::SessionStats::publish_failures},
        {"fieldgate_sparkplug_births_total", "NBIRTH and DBIRTH messages.",
         &sparkplug::SessionStats::births},
        {"fieldgate_sparkplug_deaths_total", "DDEATH and NDEATH messages published.",
         &sparkplug::SessionStats::deaths},
        {"fieldgate_sparkplug_rebirth_requests_total", "Node Control/Rebirth commands.",
         &sparkplug::SessionStats::rebirth_requests},
        {"fieldgate_sparkplug_commands_received_total", "DCMD metrics received.",
         &sparkplug::SessionStats::commands_received},
        {"fieldgate_sparkplug_commands_rejected_total",
         "DCMD metrics rejected (commands disabled, unknown or read-only metric, bad value).",
         &sparkplug::SessionStats::commands_rejected},
        {"fieldgate_sparkplug_commands_failed_total", "DCMD metrics refused or failed.",
         &sparkplug::SessionStats::commands_failed},
        {"fieldgate_sparkplug_commands_unknown_total", "DCMD metrics with an unknown outcome.",
         &sparkplug::SessionStats::commands_unknown},
        {"fieldgate_sparkplug_commands_completed_total", "DCMD metrics confirmed or done.",
         &sparkplug::SessionStats::commands_completed},
        {"fieldgate_sparkplug_malformed_messages_total",
         "Commands or STATE messages that could not be decoded.",
         &sparkplug::SessionStats::malformed_messages},
    };
    for (const auto& c : session_counters) {
      w.family(c.name, "counter", c.help);
      w.sample(c.name, "", static_cast<double>(sp->*c.field));
    }
  }
  return std::move(w).text() + render_process_metrics();
}

}  // namespace fieldgate
