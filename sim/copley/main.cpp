// fieldgate-sim-copley: Copley ASCII amplifiers (an RS-232 gateway amplifier plus CAN nodes
// behind it) on a pseudo-terminal. See README.md.

#include <memory>
#include <string>

#include "sim/common/choice_option.hpp"
#include "sim/common/duration_option.hpp"
#include "sim/common/line_simulator.hpp"
#include "sim/copley/amplifier_network.hpp"

namespace sim = fieldgate::sim;
namespace copley = fieldgate::sim::copley;

int main(int argc, char** argv) {
  sim::LineSimulator simulator("copley", "Copley ASCII amplifier simulator: serves amplifiers");
  simulator.line().terminators = "\r";
  CLI::App& app = simulator.app();
  // The command line sets the options directly; without an option, the default of the struct.
  using Options = copley::NetworkOptions;
  Options options;
  std::string nodes = "0";
  std::string axes = "1";
  app.add_option("--nodes", nodes,
                 "CAN node IDs, e.g. 0,3,5 (0 = the RS-232 gateway amplifier, "
                 "always present)");
  app.add_option("--axes", axes, "axes per amplifier: N for all, or NODE:N,... (1-3)");
  sim::add_duration(app, "--forward-us", options.forward_latency,
                    "extra latency of commands forwarded over CAN");
  sim::add_duration(app, "--boot-ms", options.boot_time,
                    "how long a node stays silent after a reset");
  app.add_flag("--stepper", options.stepper,
               "Stepnet amplifiers (microstep states 31-42), default servo");
  app.add_flag("--compact-replies", options.compact_replies,
               "reply v1200 instead of v 1200 (both are in the manual)");
  sim::add_choice(app, "--missing-axis", options.missing_axis,
                  {{"a", Options::MissingAxis::first_axis},
                   {"e33", Options::MissingAxis::parse_error},
                   {"silent", Options::MissingAxis::silent}},
                  "a command without axis letter to a multi-axis amplifier: a (goes to axis a), "
                  "e33 (parse error) or silent (no reply)");
  sim::add_choice(app, "--zero-prefix", options.zero_prefix,
                  {{"gateway", Options::ZeroPrefix::gateway},
                   {"e31", Options::ZeroPrefix::invalid_node},
                   {"e32", Options::ZeroPrefix::can_failure}},
                  "the prefix '0 ': gateway (addresses the gateway amplifier), e31 (invalid node "
                  "ID) or e32 (CAN failure after the CAN timeout)");
  sim::add_duration(app, "--can-timeout-ms", options.can_timeout,
                    "the gateway amplifier's CAN timeout: e 32 for an absent node comes this late");

  simulator.describe_baud("the gateway amplifier's current serial rate (power-up is 9600)",
                          CLI::Range(9600u, 115200u));
  return simulator.run(argc, argv, [&](sim::LineSimulator& s) {
    options.nodes = copley::parse_node_list(nodes);
    copley::parse_axes(axes, options);
    options.baud = s.baud();
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
