#include "sim/techno/exchange.hpp"

#include <utility>

namespace fieldgate::sim::techno {
namespace {

constexpr char kStop = '\xff';

LineDeviceOptions line_options(const ExchangeOptions& options) {
  LineDeviceOptions line;
  line.wire = options.wire;
  line.seed = options.seed;
  line.verbose = options.verbose;
  line.name = "techno";
  set_line_framing(line);
  return line;
}

}  // namespace

LineDeviceHooks line_hooks(Controller& controller) {
  LineDeviceHooks hooks;
  hooks.frame = [](std::string_view pending) -> std::size_t {
    const std::size_t cr = pending.find('\r');
    return cr == std::string_view::npos ? 0 : cr + 1;
  };
  hooks.respond = [&controller](std::string_view request, SimTime now) {
    request.remove_suffix(1);  // the CR
    controller.line(request, now);
    return DeviceReply{};  // the controller answers through emit()
  };
  hooks.raw_bytes = "\xfe\xff";
  hooks.raw = [&controller](char byte, SimTime now) {
    if (byte == kStop)
      controller.stop_byte(now);
    else
      controller.reset_byte(now);
    return DeviceReply{};
  };
  hooks.advance = [&controller](SimTime now) { controller.advance(now); };
  hooks.next_event = [&controller] { return controller.next_event(); };
  return hooks;
}

void set_line_framing(LineDeviceOptions& options) {
  options.terminators = "\r";
  options.dropped_after_request = "\n";
}

TechnoExchange::TechnoExchange(Controller& controller, ExchangeOptions options,
                               FaultInjection& faults)
    : line_(line_hooks(controller), line_options(options), faults) {
  controller.set_emit([this](SimTime at, std::string bytes) { line_.emit(at, bytes); });
}

}  // namespace fieldgate::sim::techno
