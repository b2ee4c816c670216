#include "gateway/config/modbus_rtu_config.hpp"

#include <fmt/format.h>

#include <set>

#include "gateway/config/gateway_config.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate {

namespace {

const Model* model_named(const GatewayConfig& config, const std::string& name) {
  for (const auto& bus : config.buses)
    for (const auto& node : bus.nodes)
      if (node.model && node.model->name == name) return node.model.get();
  return nullptr;
}

std::optional<std::chrono::milliseconds> whole_milliseconds(YamlReader& r, const YAML::Node& node,
                                                            const std::string& what) {
  const auto d = r.duration(node, what);
  if (!d) return std::nullopt;
  if (d->count() < 0 || d->count() % 1000 != 0 || *d > std::chrono::seconds(1)) {
    r.error(node, fmt::format("{}: the kernel takes whole milliseconds from 0 to 1000 ms, found "
                              "{} us",
                              what, d->count()));
    return std::nullopt;
  }
  return std::chrono::duration_cast<std::chrono::milliseconds>(*d);
}

}  // namespace

std::optional<ModbusRtuConfig> parse_modbus_rtu(YamlReader& r, const YAML::Node& node,
                                                GatewayConfig& config, const RtuParseHooks& hooks) {
  const std::string where = "modbus_rtu";
  if (!r.expect_map(node, where)) return std::nullopt;
  r.reject_unknown_keys(node,
                        {"device", "baud", "allow_nonstandard_baud", "data_bits", "parity",
                         "stop_bits", "rs485", "frame_gap", "incomplete_frame_wait",
                         "response_timeout", "slow_writes", "listener", "units", "broadcast_stop"},
                        where);
  ModbusRtuConfig rtu;
  rtu.mark = r.mark(node);
  rtu.serial.baud = 19200;
  rtu.serial.parity = 'E';
  if (auto d = r.require(node, "device", where))
    if (auto text = hooks.expand(*d, where + " device")) rtu.serial.device = *text;
  hooks.serial(node, rtu.serial, where);
  if (node["data_bits"] && rtu.serial.data_bits != 8)
    r.error(node["data_bits"], where + " data_bits: Modbus RTU uses 8 data bits");

  if (const auto rs = node["rs485"]; rs && r.expect_map(rs, where + " rs485")) {
    r.reject_unknown_keys(rs, {"enabled", "rts_on_send", "delay_before_send", "delay_after_send"},
                          where + " rs485");
    rtu.rs485 = true;
    if (rs["enabled"])
      rtu.rs485 = r.boolean(rs["enabled"], where + " rs485 enabled").value_or(true);
    if (const auto level = rs["rts_on_send"]) {
      const auto text = r.string(level, where + " rs485 rts_on_send");
      if (text && (*text == "high" || *text == "low"))
        rtu.rts_high_on_send = *text == "high";
      else if (text)
        r.error(level,
                fmt::format("{} rs485 rts_on_send: expected high or low (the RTS level while "
                            "sending), found '{}'",
                            where, *text));
    }
    if (rs["delay_before_send"])
      rtu.delay_before_send =
          whole_milliseconds(r, rs["delay_before_send"], where + " rs485 delay_before_send")
              .value_or(rtu.delay_before_send);
    if (rs["delay_after_send"])
      rtu.delay_after_send =
          whole_milliseconds(r, rs["delay_after_send"], where + " rs485 delay_after_send")
              .value_or(rtu.delay_after_send);
  }

  if (const auto gap = node["frame_gap"]) {
    rtu.frame_gap = r.duration(gap, where + " frame_gap").value_or(rtu.frame_gap);
    if (rtu.frame_gap.count() <= 0 || rtu.frame_gap > std::chrono::milliseconds(500))
      r.error(gap, where + " frame_gap: expected more than 0 and at most 500ms");
  }
  if (const auto w = node["incomplete_frame_wait"]) {
    rtu.incomplete_frame_wait =
        r.duration(w, where + " incomplete_frame_wait").value_or(rtu.incomplete_frame_wait);
    if (rtu.incomplete_frame_wait.count() < 0 ||
        rtu.incomplete_frame_wait > std::chrono::milliseconds(500))
      r.error(w, where + " incomplete_frame_wait: expected from 0 to 500ms");
  }
  if (const auto t = node["response_timeout"]) {
    rtu.response_timeout =
        r.duration(t, where + " response_timeout").value_or(rtu.response_timeout);
    if (rtu.response_timeout < std::chrono::milliseconds(20) ||
        rtu.response_timeout > std::chrono::seconds(60))
      r.error(t, where +
                     " response_timeout: expected from 20ms to 60s (set the same in the "
                     "master)");
  }
  if (const auto s = node["slow_writes"]) {
    const auto text = r.string(s, where + " slow_writes");
    if (text && *text == "acknowledge")
      rtu.slow_writes = modbus::SlowWrites::acknowledge;
    else if (text && *text == "silent")
      rtu.slow_writes = modbus::SlowWrites::silent;
    else if (text)
      r.error(s, fmt::format("{} slow_writes: expected acknowledge or silent, found '{}'", where,
                             *text));
  }

  if (const auto l = node["listener"]) {
    if (const auto name = r.string(l, where + " listener")) {
      if (const auto index = config.find_listener(*name))
        rtu.listener = *index;
      else
        r.error(l, fmt::format("{} listener: no listener is named '{}'", where, *name));
    }
  }
  std::set<uint8_t> known_units;
  for (const auto& bus : config.buses)
    for (const auto& n : bus.nodes)
      if (n.listener == rtu.listener) {
        known_units.insert(n.unit_id);
        for (const auto& [axis, id] : n.axis_units) known_units.insert(id);
      }
  if (const auto units = node["units"]; units && r.expect_sequence(units, where + " units")) {
    for (const auto& item : units) {
      const auto u = r.integer(item, where + " units", 1, 247);
      if (!u) continue;
      if (!known_units.count(static_cast<uint8_t>(*u)))
        r.error(item, fmt::format("{} units: no node on listener {} has unit_id {}", where,
                                  config.listener_name(rtu.listener), *u));
      else
        rtu.units.push_back(static_cast<uint8_t>(*u));
    }
  }

  if (const auto b = node["broadcast_stop"]; b && r.expect_map(b, where + " broadcast_stop")) {
    const std::string bw = where + " broadcast_stop";
    r.reject_unknown_keys(b, {"code", "actions"}, bw);
    if (b["code"])
      rtu.broadcast_code =
          static_cast<uint16_t>(r.integer(b["code"], bw + " code", 1, 0xFFFF).value_or(0xFFFF));
    if (auto actions = r.require(b, "actions", bw);
        actions && r.expect_map(*actions, bw + " actions")) {
      for (const auto& entry : *actions) {
        const std::string model = entry.first.Scalar();
        const auto action = r.string(entry.second, bw + " actions " + model);
        if (!action) continue;
        const Model* m = model_named(config, model);
        if (!m) {
          config.warnings.push_back(
              fmt::format("{}: {}: no node uses model {}; its entry has no "
                          "effect",
                          to_string(r.mark(entry.first)), bw, model));
          continue;
        }
        if (!m->find_action(*action)) {
          std::string known;
          for (const auto& a : m->actions) known += (known.empty() ? "" : ", ") + a.name;
          r.error(entry.second, fmt::format("{}: model {} has no action '{}' (actions: {})", bw,
                                            model, *action, known));
          continue;
        }
        rtu.broadcast_actions[model] = *action;
      }
    }
  }
  return rtu;
}

}  // namespace fieldgate
