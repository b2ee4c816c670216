// fieldgate-sim-copley: Copley ASCII amplifiers (an RS-232 gateway amplifier plus CAN nodes
// behind it) on a pseudo-terminal. See README.md.

#include <memory>
#include <string>

#include "sim/common/choice_option.hpp"
#include "sim/common/line_simulator.hpp"
#include "sim/copley/amplifier_network.hpp"

namespace sim = fieldgate::sim;
namespace copley = fieldgate::sim::copley;

int main(int argc, char** argv) {
  sim::LineSimulator simulator("copley", "Copley ASCII amplifier simulator: serves amplifiers");
  simulator.line().terminators = "\r";
  CLI::App& app = simulator.app();
  std::string nodes = "0";
  std::string axes = "1";
  long forward_us = 0;
  long boot_ms = 0;
  bool stepper = false;
  bool compact = false;
  using Options = copley::NetworkOptions;
  auto missing_axis = Options::MissingAxis::first_axis;
  auto zero_prefix = Options::ZeroPrefix::gateway;
  long can_timeout_ms = 0;
  app.add_option("--nodes", nodes,
                 "CAN node IDs, e.g. 0,3,5 (0 = the RS-232 gateway amplifier, "
                 "always present)");
  app.add_option("--axes", axes, "axes per amplifier: N for all, or NODE:N,... (1-3)");
  app.add_option("--forward-us", forward_us, "extra latency of commands forwarded over CAN")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--boot-ms", boot_ms, "how long a node stays silent after a reset")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--stepper", stepper, "Stepnet amplifiers (microstep states 31-42), default servo");
  app.add_flag("--compact-replies", compact,
               "reply v1200 instead of v 1200 (both are in the manual)");
  sim::add_choice(app, "--missing-axis", missing_axis,
                  {{"a", Options::MissingAxis::first_axis},
                   {"e33", Options::MissingAxis::parse_error},
                   {"silent", Options::MissingAxis::silent}},
                  "a command without axis letter to a multi-axis amplifier: a (goes to axis a), "
                  "e33 (parse error) or silent (no reply)");
  sim::add_choice(app, "--zero-prefix", zero_prefix,
                  {{"gateway", Options::ZeroPrefix::gateway},
                   {"e31", Options::ZeroPrefix::invalid_node},
                   {"e32", Options::ZeroPrefix::can_failure}},
                  "the prefix '0 ': gateway (addresses the gateway amplifier), e31 (invalid node "
                  "ID) or e32 (CAN failure after the CAN timeout)");
  app.add_option("--can-timeout-ms", can_timeout_ms,
                 "the gateway amplifier's CAN timeout: e 32 for an absent node comes this late")
      ->check(CLI::NonNegativeNumber);

  simulator.describe_baud("the gateway amplifier's current serial rate (power-up is 9600)",
                          CLI::Range(9600u, 115200u));
  return simulator.run(argc, argv, [&](sim::LineSimulator& s) {
    Options options;
    options.nodes = copley::parse_node_list(nodes);
    copley::parse_axes(axes, options);
    options.stepper = stepper;
    options.baud = s.baud();
    options.forward_latency = std::chrono::microseconds(forward_us);
    options.boot_time = std::chrono::milliseconds(boot_ms);
    options.compact_replies = compact;
    options.missing_axis = missing_axis;
    options.zero_prefix = zero_prefix;
    options.can_timeout = std::chrono::milliseconds(can_timeout_ms);
    auto network = std::make_shared<copley::AmplifierNetwork>(options, s.start());

    sim::LineFamily family;
    family.device = network;
    family.hooks = sim::request_hooks(*network);
    family.control = [network, &s](std::string_view verb, std::span<const std::string> arguments) {
      std::optional<std::uint32_t> link_baud;
      auto reply = network->control(verb, arguments, sim::SimClock::now(), link_baud);
      if (link_baud) s.exchange().set_baud(*link_baud);
      return reply;
    };
    family.control_help = copley::AmplifierNetwork::control_help();
    return family;
  });
}
