#include "gateway/console/plant_view.hpp"

#include <boost/json.hpp>

#include <cstdint>

#include "gateway/bus/wire_trace.hpp"
#include "gateway/console/fleet_watch.hpp"
#include "gateway/gateway.hpp"
#include "gateway/register_map/axis_profile_server.hpp"

namespace fieldgate {

namespace json = boost::json;

namespace {

// An integer: as a double, Boost.JSON writes it in exponent notation (1.7966E12).
std::int64_t epoch_ms(std::chrono::system_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
}

std::string link_of(const BusConfig& bus) {
  switch (bus.transport.kind) {
    case TransportConfig::Kind::serial:
      return bus.transport.serial.device;
    case TransportConfig::Kind::tcp:
      return bus.transport.host + ":" + std::to_string(bus.transport.port);
    case TransportConfig::Kind::can:
      return bus.transport.can_interface;
  }
  return {};
}

// The counters buses and nodes both keep, under the same names.
template <typename Counters>
void put_exchange_counters(json::object& o, const Counters& c) {
  o["transactions"] = c.transactions;
  o["timeouts"] = c.timeouts;
  o["errors"] = c.errors;
  o["retries"] = c.retries;
  o["unreachable"] = c.unreachable;
}

json::object bus_view(const Bus& bus) {
  const BusCounters& c = bus.counters();
  const BusConfig& config = bus.config();
  json::object o;
  o["name"] = config.name;
  o["protocol"] = config.protocol;
  o["link"] = link_of(config);
  o["link_up"] = c.link_up;
  put_exchange_counters(o, c);
  o["reconnects"] = c.reconnects;
  o["resyncs"] = c.resyncs;
  o["alignment_proofs"] = c.alignment_proofs;
  o["alignment_failures"] = c.alignment_failures;
  bool trace = false;
  for (const auto* t : WireTrace::all()) trace = trace || (t->bus() == config.name && t->enabled());
  o["trace"] = trace;
  return o;
}

json::object node_view(const BusConfig& bus, const NodeConfig& config, const NodeImage& image,
                       std::chrono::steady_clock::time_point now) {
  const NodeCounters& c = image.counters;
  json::object o;
  o["name"] = config.name;
  o["bus"] = bus.name;
  o["address"] = config.address.text;
  o["model"] = config.model ? config.model->name : std::string();
  o["unit"] = config.unit_id;
  o["state"] = std::string(to_string(image.state));
  // Why a node that is not online is not: the last failure as the log words it.
  o["reason"] = image.state == NodeState::online ? std::string() : c.last_error_text;
  put_exchange_counters(o, c);
  o["unknown_writes"] = c.unknown_writes;
  o["consecutive_timeouts"] = c.consecutive_timeouts;
  if (c.ever_good)
    o["last_good_age_ms"] =
        std::chrono::duration_cast<std::chrono::milliseconds>(now - c.last_good).count();
  else
    o["last_good_age_ms"] = nullptr;
  o["last_device_error"] = c.last_device_error;
  o["last_error_text"] = c.last_error_text;
  return o;
}

json::array status_names(uint16_t word) {
  json::array names;
  for (int b = 0; b < kStatusBitCount; ++b)
    if (word & (1u << b)) names.emplace_back(std::string(to_string(static_cast<StatusBit>(b))));
  return names;
}

json::object axis_view(const ProfileUnit& unit, const NodeImage& image, uint8_t unit_id,
                       const std::string& listener) {
  const auto& def = unit.model->profile_axes[static_cast<std::size_t>(unit.axis)];
  const std::size_t slot = static_cast<std::size_t>(unit.axis);
  // Until a PLC first reads or commands the axis, its runtime is the default one.
  const ProfileAxisRuntime none;
  const ProfileAxisRuntime& rt = slot < image.profile_axes.size() ? image.profile_axes[slot] : none;
  const AxisReading r = read_axis(unit, image, rt);
  json::object o;
  o["name"] = unit.node->name + "/" + def.name;
  o["node"] = unit.node->name;
  o["axis"] = def.name;
  o["unit"] = unit_id;
  o["listener"] = listener;
  o["online"] = r.online;
  o["state"] = std::string(to_string(r.state));
  if (r.position)
    o["position"] = *r.position;
  else
    o["position"] = nullptr;
  if (r.velocity)
    o["velocity"] = *r.velocity;
  else
    o["velocity"] = nullptr;
  o["status"] = status_names(r.status_word);
  o["error_id"] = r.error_id;
  o["command"] = std::string(to_string(r.command));
  o["command_status"] = std::string(to_string(r.status));
  o["command_error"] = r.command_error;
  o["sequence"] = r.sequence;
  return o;
}

json::object listener_view(const Gateway::Listener& l) {
  json::object o;
  o["name"] = l.name;
  if (!l.server) return o;
  const auto& s = l.server->stats();
  o["clients_connected"] = s.clients_connected;
  o["clients_accepted"] = s.clients_accepted;
  o["clients_refused"] = s.clients_refused;
  o["clients_denied"] = s.clients_denied;
  o["clients_timed_out"] = s.clients_timed_out;
  o["framing_errors"] = s.framing_errors;
  json::array functions;
  for (std::size_t f = 0; f < s.functions.size(); ++f) {
    if (s.functions[f].requests == 0) continue;
    json::object fo;
    fo["function"] = f;
    fo["requests"] = s.functions[f].requests;
    fo["exceptions"] = s.functions[f].exceptions;
    functions.push_back(std::move(fo));
  }
  o["functions"] = std::move(functions);
  json::array clients;
  for (const auto& c : l.server->clients()) {
    json::object co;
    co["address"] = c.address;
    co["port"] = c.port;
    co["connected_s"] = std::chrono::duration_cast<std::chrono::seconds>(c.connected_for).count();
    co["idle_ms"] = std::chrono::duration_cast<std::chrono::milliseconds>(c.idle).count();
    co["requests"] = c.requests;
    co["exceptions"] = c.exceptions;
    clients.push_back(std::move(co));
  }
  o["clients"] = std::move(clients);
  return o;
}

json::array metrics_view(const std::map<std::string, sparkplug::FleetView::MetricState>& metrics) {
  json::array out;
  for (const auto& [name, m] : metrics) {
    json::object o;
    o["name"] = name;
    o["value"] = m.value;
    o["datatype"] = m.datatype;
    out.push_back(std::move(o));
  }
  return out;
}

json::object fleet_view(const FleetWatch& fleet) {
  json::object o;
  o["group"] = fleet.config().group_id;
  o["broker"] = fleet.config().host + ":" + std::to_string(fleet.config().port);
  o["connected"] = fleet.connected();
  o["malformed"] = fleet.view().malformed();
  json::array nodes;
  for (const auto& [name, n] : fleet.view().edge_nodes()) {
    json::object no;
    no["name"] = name;
    no["born"] = n.born;
    if (n.bd_seq)
      no["bd_seq"] = *n.bd_seq;
    else
      no["bd_seq"] = nullptr;
    no["messages"] = n.messages;
    no["seq_gaps"] = n.seq_gaps;
    no["changed_ms"] = n.changed_ms;
    no["metrics"] = metrics_view(n.metrics);
    json::array devices;
    for (const auto& [dname, d] : n.devices) {
      json::object dobj;
      dobj["name"] = dname;
      dobj["born"] = d.born;
      dobj["messages"] = d.messages;
      dobj["changed_ms"] = d.changed_ms;
      dobj["metrics"] = metrics_view(d.metrics);
      devices.push_back(std::move(dobj));
    }
    no["devices"] = std::move(devices);
    nodes.push_back(std::move(no));
  }
  o["edge_nodes"] = std::move(nodes);
  json::object hosts;
  for (const auto& [id, state] : fleet.view().hosts()) hosts[id] = state;
  o["hosts"] = std::move(hosts);
  return o;
}

}  // namespace

std::string plant_json(const Gateway& gateway, std::chrono::steady_clock::time_point now,
                       std::chrono::system_clock::time_point wall, const FleetWatch* fleet) {
  const auto& config = gateway.config().gateway;
  const auto& image = gateway.image();
  json::object root;
  root["time_ms"] = epoch_ms(wall);
  json::array buses;
  for (const auto& bus : gateway.buses()) buses.push_back(bus_view(*bus));
  root["buses"] = std::move(buses);
  json::array nodes, axes;
  int index = 0;
  for (const auto& bus : config.buses)
    for (const auto& node : bus.nodes) {
      const NodeImage& ni = image.node(index);
      nodes.push_back(node_view(bus, node, ni, now));
      for (const auto& [axis_name, unit_id] : node.axis_units)
        if (const auto* def = node.model->find_profile_axis(axis_name)) {
          const ProfileUnit unit{index, &node, node.model,
                                 static_cast<int>(def - node.model->profile_axes.data())};
          axes.push_back(axis_view(unit, ni, unit_id, config.listener_name(node.listener)));
        }
      ++index;
    }
  root["nodes"] = std::move(nodes);
  root["axes"] = std::move(axes);
  json::array listeners;
  for (const auto& l : gateway.listeners()) listeners.push_back(listener_view(l));
  root["listeners"] = std::move(listeners);
  if (fleet)
    root["fleet"] = fleet_view(*fleet);
  else
    root["fleet"] = nullptr;
  return json::serialize(root);
}

}  // namespace fieldgate
