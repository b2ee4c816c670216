#include "gateway/modbus/modbus_rtu_port.hpp"

#include <fmt/format.h>

#include <set>

#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

namespace {

std::string parity_name(char parity) {
  return parity == 'E' ? "even" : parity == 'O' ? "odd" : "none";
}

}  // namespace

modbus::ModbusRtuServerOptions rtu_server_options(const LoadedConfig& config) {
  const ModbusRtuConfig& rtu = *config.gateway.modbus_rtu;
  modbus::ModbusRtuServerOptions o;
  o.serial = {rtu.serial.device, rtu.serial.baud, rtu.serial.data_bits, rtu.serial.parity,
              rtu.serial.stop_bits};
  o.rs485 = {rtu.rs485, rtu.rts_high_on_send, rtu.delay_before_send, rtu.delay_after_send};
  o.frame_gap = rtu.frame_gap;
  o.incomplete_frame_wait = rtu.incomplete_frame_wait;
  o.response_timeout = rtu.response_timeout;
  o.slow_writes = rtu.slow_writes;
  if (rtu.units.empty()) {
    for (const auto& [id, unit] : config.map_of(config.gateway.modbus_rtu->listener).units())
      o.units.set(id);
    // Profile units (docs/axis-profile.md) are served like native ones.
    for (const auto& bus : config.gateway.buses)
      for (const auto& node : bus.nodes)
        if (node.listener == rtu.listener)
          for (const auto& [axis, id] : node.axis_units) o.units.set(id);
  } else {
    for (const auto id : rtu.units) o.units.set(id);
  }
  o.broadcast.address = layout::action_block;
  o.broadcast.value = rtu.broadcast_code;
  std::set<std::string> bus_wide_sent;
  for (const auto& [id, unit] : config.map_of(config.gateway.modbus_rtu->listener).units()) {
    if (!o.units.test(id)) continue;
    const auto it = rtu.broadcast_actions.find(unit.model->name);
    if (it == rtu.broadcast_actions.end()) continue;
    const ActionDef* action = unit.model->find_action(it->second);
    if (!action) continue;
    if (action->bus_wide && !bus_wide_sent.insert(unit.bus_name).second) continue;
    o.broadcast.writes.push_back({id, action->code});
  }
  o.notice = [](const std::string& text) { log::notice("{}", text); };
  o.warning = [](const std::string& text) { log::warning("{}", text); };
  o.debug = [](const std::string& text) { log::debug("{}", text); };
  return o;
}

std::string describe_modbus_rtu(const LoadedConfig& config) {
  if (!config.gateway.modbus_rtu) return {};
  const ModbusRtuConfig& rtu = *config.gateway.modbus_rtu;
  const auto o = rtu_server_options(config);
  std::string units;
  for (std::size_t id = 1; id < 248; ++id)
    if (o.units.test(id)) units += (units.empty() ? "" : ", ") + std::to_string(id);
  std::string out = fmt::format(
      "\n## Modbus RTU port\n\n"
      "| setting | value |\n|---|---|\n"
      "| device | {} |\n| serial | {} baud, {} data bits, parity {}, {} stop bit(s) |\n"
      "| RS-485 direction | {} |\n| frame gap (t3.5) | {} us |\n"
      "| master response timeout | {} ms (answers are sent within {} ms) |\n"
      "| slow confirmed writes | {} |\n| units served | {} |\n",
      rtu.serial.device, rtu.serial.baud, rtu.serial.data_bits, parity_name(rtu.serial.parity),
      rtu.serial.stop_bits,
      rtu.rs485 ? fmt::format("kernel (TIOCSRS485), RTS {} while sending, delays {}/{} ms",
                              rtu.rts_high_on_send ? "high" : "low", rtu.delay_before_send.count(),
                              rtu.delay_after_send.count())
                : "none (RS-232, or an adapter with automatic direction)",
      std::chrono::duration_cast<std::chrono::microseconds>(o.silent_interval()).count(),
      std::chrono::duration_cast<std::chrono::milliseconds>(o.response_timeout).count(),
      std::chrono::duration_cast<std::chrono::milliseconds>(o.answer_window()).count(),
      rtu.slow_writes == modbus::SlowWrites::acknowledge
          ? "exception 0x05 (acknowledge) when not confirmed in time; the write goes on"
          : "no answer when not confirmed in time; the write goes on",
      units.empty() ? "none" : units);
  if (o.broadcast.writes.empty()) {
    out += "\nBroadcasts (unit 0) are never answered; none is carried out (no broadcast_stop).\n";
    return out;
  }
  out += fmt::format(
      "\nBroadcast stop: write {} (0x{:04X}) to holding register {} of unit 0 (function 0x06, or "
      "0x10 with one register). Never answered; every other broadcast is dropped. It writes:\n\n"
      "| unit | node | model | action | code |\n|---|---|---|---|---|\n",
      o.broadcast.value, o.broadcast.value, o.broadcast.address);
  for (const auto& w : o.broadcast.writes) {
    const UnitMap* unit = config.map_of(config.gateway.modbus_rtu->listener).unit(w.unit);
    const ActionDef* action = unit->model->find_action(w.value);
    out += fmt::format("| {} | {} | {} | {}{} | {} |\n", w.unit, unit->node_name, unit->model->name,
                       action->name, action->bus_wide ? " (bus-wide: once per bus)" : "", w.value);
  }
  return out;
}

void ModbusRtuPort::apply(const LoadedConfig& config,
                          std::shared_ptr<modbus::RequestHandler> handler) {
  if (!config.gateway.modbus_rtu) {
    stop();
    return;
  }
  auto options = rtu_server_options(config);
  if (server_) {
    server_->set_handler(handler);
    if (server_->reconfigure(options)) return;
    log::warning("modbus rtu: the port's settings changed; reopening it");
    server_->stop();
  }
  server_ = std::make_unique<modbus::ModbusRtuServer>(io_.get_executor(), std::move(options),
                                                      std::move(handler));
  server_->start();
}

void ModbusRtuPort::stop() {
  if (server_) server_->stop();
  server_.reset();
}

}  // namespace fieldgate
