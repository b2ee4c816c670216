// fieldgate-sim-techno: a Techno/isel C-series controller (IT116G, C10, C116, C142) on a
// pseudo-terminal. See README.md.

#include <memory>
#include <stdexcept>
#include <string>

#include "sim/common/choice_option.hpp"
#include "sim/common/line_simulator.hpp"
#include "sim/techno/controller.hpp"
#include "sim/techno/exchange.hpp"

namespace sim = fieldgate::sim;
namespace techno = fieldgate::sim::techno;

int main(int argc, char** argv) {
  sim::LineSimulator simulator("techno",
                               "Techno/isel C-series controller simulator: serves one controller");
  techno::set_line_framing(simulator.line());
  CLI::App& app = simulator.app();
  std::string variant = "c142";
  int device = 0;
  int axes = -1;
  int accel = -1;
  double home_distance = 5000;
  double travel = 100000;
  bool no_mechanics = false;
  bool queries_during_motion = true;
  bool position_ack = false;
  bool no_cr = false;
  bool stop_ack = false;
  app.add_option("--variant", variant, "it116g, c10, c116 or c142")
      ->check(CLI::IsMember({"it116g", "c10", "c116", "c142"}));
  app.add_option("--device", device, "device number GN of @<GN> (0-9; the standard is 0)")
      ->check(CLI::Range(0, 9));
  app.add_option("--axes", axes,
                 "axes already defined at start (1, 3, 5, 7); default none: every command "
                 "answers 4 until the host sends @<GN><axes>")
      ->check(CLI::IsMember({1, 3, 5, 7}));
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
  sim::add_choice(app, "--queries-during-motion", queries_during_motion,
                  {{"answer", true}, {"defer", false}},
                  "answer: P/b/c are answered during a lower-case motion; defer: they wait for "
                  "its end like every other command");
  app.add_flag("--position-ack", position_ack, "send the 0 handshake before the P data");
  app.add_flag("--no-cr", no_cr, "no CR after the data of P and b/c");
  app.add_flag("--stop-ack", stop_ack, "a capital command ended by STOP still answers 0");

  simulator.describe_baud("link rate for --emulate-wire (2400, 4800, 9600, 19200)",
                          CLI::IsMember({2400u, 4800u, 9600u, 19200u}));
  return simulator.run(argc, argv, [&](sim::LineSimulator& s) {
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
    options.queries_during_motion = queries_during_motion;
    options.position_ack = position_ack;
    options.reply_cr = !no_cr;
    options.stop_acknowledges = stop_ack;
    auto controller = std::make_shared<techno::Controller>(options, s.start());
    controller->set_emit(
        [&s](sim::SimTime at, std::string bytes) { s.exchange().emit(at, bytes); });

    return sim::line_family(controller, techno::line_hooks(*controller));
  });
}
