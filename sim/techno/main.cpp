// fieldgate-sim-techno: a Techno/isel C-series controller (IT116G, C10, C116, C142) on a
// pseudo-terminal. See README.md.

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <string>

#include "sim/common/control_channel.hpp"
#include "sim/common/pty_port.hpp"
#include "sim/techno/controller.hpp"
#include "sim/techno/exchange.hpp"

namespace sim = fieldgate::sim;
namespace techno = fieldgate::sim::techno;

int main(int argc, char** argv) {
  CLI::App app{
      "Techno/isel C-series controller simulator: serves one controller on a pseudo-terminal; "
      "control commands on stdin (type help)."};
  std::string link;
  std::string variant = "c142";
  int device = 0;
  int axes = -1;
  std::uint32_t baud = 9600;
  int accel = -1;
  double home_distance = 5000;
  double travel = 100000;
  bool no_mechanics = false;
  std::string queries = "answer";
  bool position_ack = false;
  bool no_cr = false;
  bool stop_ack = false;
  bool emulate_wire = false;
  long turnaround_us = -1;
  bool verbose = false;
  std::uint32_t seed = 1;
  app.add_option("--link", link, "symlink to create for the PTY slave, e.g. /tmp/techno0");
  app.add_option("--variant", variant, "it116g, c10, c116 or c142")
      ->check(CLI::IsMember({"it116g", "c10", "c116", "c142"}));
  app.add_option("--device", device, "device number GN of @<GN> (0-9; the standard is 0)")
      ->check(CLI::Range(0, 9));
  app.add_option("--axes", axes,
                 "axes already defined at start (1, 3, 5, 7); default none: every command "
                 "answers 4 until the host sends @<GN><axes>")
      ->check(CLI::IsMember({1, 3, 5, 7}));
  app.add_option("--baud", baud, "link rate for --emulate-wire (2400, 4800, 9600, 19200)")
      ->check(CLI::IsMember({2400u, 4800u, 9600u, 19200u}));
  app.add_option("--accel", accel,
                 "acceleration jumper in Hz/ms (25, 50, 75, 100; default 25 IT116G, 75 cards)")
      ->check(CLI::IsMember({25, 50, 75, 100}));
  app.add_option("--home-distance", home_distance,
                 "steps between each axis and its home switch at start")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--travel", travel, "machine range from the home switch; moves beyond answer 2")
      ->check(CLI::PositiveNumber);
  app.add_flag("--no-mechanics", no_mechanics,
               "homing never finds a switch and never answers (manual p.41)");
  app.add_option("--queries-during-motion", queries,
                 "answer: P/b/c are answered during a lower-case motion; defer: they wait for "
                 "its end like every other command")
      ->check(CLI::IsMember({"answer", "defer"}));
  app.add_flag("--position-ack", position_ack, "send the 0 handshake before the P data");
  app.add_flag("--no-cr", no_cr, "no CR after the data of P and b/c");
  app.add_flag("--stop-ack", stop_ack, "a capital command ended by STOP still answers 0");
  app.add_flag("--emulate-wire", emulate_wire,
               "take as long as the bytes would take on a real line at --baud");
  app.add_option("--turnaround-us", turnaround_us,
                 "processing time before a reply (default 0, or 1000 with --emulate-wire)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--seed", seed, "seed for garbage replies");
  app.add_flag("--verbose", verbose, "log every line, raw byte and reply to stderr");
  CLI11_PARSE(app, argc, argv);

  try {
    techno::ControllerOptions options;
    options.variant = *techno::parse_variant(variant);
    options.device = device;
    if (axes > 0) {
      if (options.variant == techno::Variant::it116g && axes != 1)
        throw std::invalid_argument("the IT116G has one axis: --axes 1");
      options.axes = axes;
    }
    const int jumper = accel > 0 ? accel : (options.variant == techno::Variant::it116g ? 25 : 75);
    options.acceleration = jumper * 1000.0;
    options.home_distance = home_distance;
    options.travel = travel;
    options.mechanics = !no_mechanics;
    options.queries_during_motion = queries == "answer";
    options.position_ack = position_ack;
    options.reply_cr = !no_cr;
    options.stop_acknowledges = stop_ack;
    techno::Controller controller(options, sim::SimClock::now());

    techno::ExchangeOptions exchange_options;
    exchange_options.wire.enabled = emulate_wire;
    exchange_options.wire.timing = sim::WireTiming(baud);
    exchange_options.wire.turnaround =
        std::chrono::microseconds(turnaround_us >= 0 ? turnaround_us : (emulate_wire ? 1000 : 0));
    exchange_options.seed = seed;
    exchange_options.verbose = verbose;

    sim::FaultInjection faults;
    techno::TechnoExchange exchange(controller, exchange_options, faults);
    sim::ControlChannel control(
        STDIN_FILENO, STDOUT_FILENO, faults,
        [&](std::string_view verb, std::span<const std::string> arguments) {
          return controller.control(verb, arguments, sim::SimClock::now());
        },
        techno::Controller::control_help());

    sim::PtyPort port(link);
    std::printf("ready %s %s\n", link.empty() ? port.slave_name().c_str() : link.c_str(),
                port.slave_name().c_str());
    std::fflush(stdout);
    techno::run_techno_device(port, control, exchange);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fieldgate-sim-techno: %s\n", e.what());
    return 1;
  }
  return 0;
}
