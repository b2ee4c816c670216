// fieldgate-sim-copley: Copley ASCII amplifiers (an RS-232 gateway amplifier plus CAN nodes
// behind it) on a pseudo-terminal. See README.md.

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>

#include "sim/common/control_channel.hpp"
#include "sim/common/line_device_loop.hpp"
#include "sim/common/pty_port.hpp"
#include "sim/copley/amplifier_network.hpp"

namespace sim = fieldgate::sim;
namespace copley = fieldgate::sim::copley;

int main(int argc, char** argv) {
  CLI::App app{
      "Copley ASCII amplifier simulator: serves amplifiers on a pseudo-terminal; "
      "control commands on stdin (type help)."};
  std::string link;
  std::string nodes = "0";
  std::string axes = "1";
  std::uint32_t baud = 9600;
  bool emulate_wire = false;
  long turnaround_us = -1;
  long forward_us = 0;
  long boot_ms = 0;
  bool stepper = false;
  bool compact = false;
  bool verbose = false;
  std::uint32_t seed = 1;
  std::string missing_axis = "a";
  std::string zero_prefix = "gateway";
  long can_timeout_ms = 0;
  std::string journal_path;
  std::string wire_log_path;
  app.add_option("--link", link, "symlink to create for the PTY slave, e.g. /tmp/copley0");
  app.add_option("--nodes", nodes,
                 "CAN node IDs, e.g. 0,3,5 (0 = the RS-232 gateway amplifier, "
                 "always present)");
  app.add_option("--axes", axes, "axes per amplifier: N for all, or NODE:N,... (1-3)");
  app.add_option("--baud", baud, "the gateway amplifier's current serial rate (power-up is 9600)")
      ->check(CLI::Range(9600u, 115200u));
  app.add_flag("--emulate-wire", emulate_wire,
               "take as long as the bytes would take on a real line at the current baud");
  app.add_option("--turnaround-us", turnaround_us,
                 "device processing time before a reply (default 0, or 1000 with --emulate-wire)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--forward-us", forward_us, "extra latency of commands forwarded over CAN")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--boot-ms", boot_ms, "how long a node stays silent after a reset")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--stepper", stepper, "Stepnet amplifiers (microstep states 31-42), default servo");
  app.add_flag("--compact-replies", compact,
               "reply v1200 instead of v 1200 (both are in the manual)");
  app.add_option("--missing-axis", missing_axis,
                 "a command without axis letter to a multi-axis amplifier: a (goes to axis a), "
                 "e33 (parse error) or silent (no reply)")
      ->check(CLI::IsMember({"a", "e33", "silent"}));
  app.add_option("--zero-prefix", zero_prefix,
                 "the prefix '0 ': gateway (addresses the gateway amplifier), e31 (invalid node "
                 "ID) or e32 (CAN failure after the CAN timeout)")
      ->check(CLI::IsMember({"gateway", "e31", "e32"}));
  app.add_option("--can-timeout-ms", can_timeout_ms,
                 "the gateway amplifier's CAN timeout: e 32 for an absent node comes this late")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--wire-log", wire_log_path,
                 "append a line per request: first byte and arrival (CLOCK_MONOTONIC ns), "
                 "request, echo and reply bytes, device delay (for benchmarks)");
  app.add_option("--journal", journal_path,
                 "append every executed request and the device's reply to this file");
  app.add_option("--seed", seed, "seed for garbage replies");
  app.add_flag("--verbose", verbose, "log every request and reply to stderr");
  CLI11_PARSE(app, argc, argv);

  try {
    const sim::SimTime now = sim::SimClock::now();
    copley::NetworkOptions network_options;
    network_options.nodes = copley::parse_node_list(nodes);
    copley::parse_axes(axes, network_options);
    network_options.stepper = stepper;
    network_options.baud = baud;
    network_options.forward_latency = std::chrono::microseconds(forward_us);
    network_options.boot_time = std::chrono::milliseconds(boot_ms);
    network_options.compact_replies = compact;
    using Options = copley::NetworkOptions;
    network_options.missing_axis = missing_axis == "e33"      ? Options::MissingAxis::parse_error
                                   : missing_axis == "silent" ? Options::MissingAxis::silent
                                                              : Options::MissingAxis::first_axis;
    network_options.zero_prefix = zero_prefix == "e31"   ? Options::ZeroPrefix::invalid_node
                                  : zero_prefix == "e32" ? Options::ZeroPrefix::can_failure
                                                         : Options::ZeroPrefix::gateway;
    network_options.can_timeout = std::chrono::milliseconds(can_timeout_ms);
    copley::AmplifierNetwork network(network_options, now);

    sim::LineDeviceOptions line_options;
    line_options.wire.enabled = emulate_wire;
    line_options.wire.timing = sim::WireTiming(baud);
    line_options.wire.turnaround =
        std::chrono::microseconds(turnaround_us >= 0 ? turnaround_us : (emulate_wire ? 1000 : 0));
    line_options.terminators = "\r";
    line_options.seed = seed;
    line_options.verbose = verbose;
    line_options.name = "copley";
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> journal(nullptr, &std::fclose);
    if (!journal_path.empty()) {
      journal.reset(std::fopen(journal_path.c_str(), "a"));
      if (!journal) throw std::runtime_error("cannot open journal " + journal_path);
      line_options.journal = journal.get();
    }
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> wire_log(nullptr, &std::fclose);
    if (!wire_log_path.empty()) {
      wire_log.reset(std::fopen(wire_log_path.c_str(), "a"));
      if (!wire_log) throw std::runtime_error("cannot open wire log " + wire_log_path);
      line_options.wire_log = wire_log.get();
    }

    sim::FaultInjection faults;
    sim::LineExchange exchange(
        {.frame = &copley::AmplifierNetwork::frame,
         .respond = [&](std::string_view request,
                        sim::SimTime at) { return network.handle(request, at); },
         .echo = {}},
        line_options, faults);
    sim::ControlChannel control(
        STDIN_FILENO, STDOUT_FILENO, faults,
        [&](std::string_view verb, std::span<const std::string> arguments) {
          std::optional<std::uint32_t> link_baud;
          auto reply = network.control(verb, arguments, sim::SimClock::now(), link_baud);
          if (link_baud) exchange.set_baud(*link_baud);
          return reply;
        },
        copley::AmplifierNetwork::control_help());

    sim::PtyPort port(link);
    // Tests and scripts wait for this line before opening the port.
    std::printf("ready %s %s\n", link.empty() ? port.slave_name().c_str() : link.c_str(),
                port.slave_name().c_str());
    std::fflush(stdout);
    sim::run_line_device(port, control, exchange);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fieldgate-sim-copley: %s\n", e.what());
    return 1;
  }
  return 0;
}
