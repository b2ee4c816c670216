// fieldgate-sim-centent: a daisy chain of Centent CN0170 two-axis controllers on a
// pseudo-terminal. See README.md.

#include <memory>
#include <string>

#include "sim/centent/daisy_chain.hpp"
#include "sim/common/choice_option.hpp"
#include "sim/common/line_simulator.hpp"

namespace sim = fieldgate::sim;
namespace centent = fieldgate::sim::centent;

int main(int argc, char** argv) {
  sim::LineSimulator simulator("centent",
                               "Centent CN0170 daisy-chain simulator: serves a chain of units");
  simulator.line().name = "cn0170";
  CLI::App& app = simulator.app();
  std::string units = "0";
  long hop_delay_us = 0;
  bool initialised = false;
  bool power_up = false;
  std::string prefix_separator;
  bool lenient_autobaud = false;
  bool select_self_after_reset = true;
  bool kill_upstream = false;
  bool prefix_unit_messages = false;
  bool position_reply_xp = false;
  bool signed_absolute = false;
  std::string terminator = "\r";
  struct OverflowSpellings {
    bool backslash = true;
    bool plain = true;
  } overflow;
  std::size_t queue = 20;
  app.add_option("--units", units,
                 "unit numbers in chain order, nearest the host first, e.g. 0,1,2 (duplicates "
                 "allowed)");
  app.add_option("--hop-delay-us", hop_delay_us,
                 "store-and-forward latency per unit passed, each way")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--initialised", initialised,
               "start as if the host had already sent the auto-baud CR (default: as after "
               "power-on, every unit waits for it, manual p.1)");
  app.add_flag("--lenient-autobaud", lenient_autobaud,
               "a unit waiting for its auto-baud CR locks on the next CR even after other "
               "characters (default: they make it fail until the next reset, as p.1 says)");
  sim::add_choice(app, "--select-after-reset", select_self_after_reset,
                  {{"self", true}, {"none", false}},
                  "self: a unit selects itself after power-up (as a lone unit must); none");
  app.add_flag("--kill-upstream", kill_upstream,
               "units a K passes on its way to the selected unit obey it too");
  app.add_flag("--prefix-unit-messages", prefix_unit_messages,
               "prefix [Un] and U<n> with the unit number as well");
  app.add_flag("--power-up", power_up, "start as after power-on (the default; kept for scripts)");
  sim::add_choice(app, "--prefix-separator", prefix_separator,
                  {{"none", ""}, {"space", " "}, {"colon", ":"}},
                  "between a unit's digit and its message (the manual never shows one): none "
                  "(2X=…h), space (2 X=…h) or colon (2:X=…h)");
  sim::add_choice(app, "--position-reply", position_reply_xp, {{"x", false}, {"xp", true}},
                  "x: X=…h (p.35); xp: XP=…h (p.2)");
  sim::add_choice(app, "--absolute-compare", signed_absolute,
                  {{"unsigned", false}, {"signed", true}},
                  "how an absolute target is compared with the position (\"positive only\", "
                  "§9 #20): unsigned (a move to the other side of 0 runs the long way round the "
                  "register) or signed (it crosses 0)");
  sim::add_choice(app, "--terminator", terminator, {{"cr", "\r"}, {"crlf", "\r\n"}, {"lf", "\n"}},
                  "reply terminator");
  sim::add_choice(app, "--overflow-mnemonic", overflow,
                  {{"backslash", {true, false}}, {"plain", {false, true}}, {"both", {true, true}}},
                  "which spelling of the overflow mode the units accept: backslash (M1\\-), "
                  "plain (M1-) or both");
  app.add_option("--queue", queue, "Immediate Queue length (the manual says about 20)")
      ->check(CLI::Range(std::size_t{3}, std::size_t{1000}));

  simulator.describe_baud("line rate for --emulate-wire (the units auto-baud to the host)",
                          CLI::Range(150u, 115200u));
  return simulator.run(argc, argv, [&](sim::LineSimulator& s) {
    centent::ChainOptions options;
    options.units = centent::parse_unit_list(units);
    options.power_up = power_up || !initialised;
    options.prefix_separator = prefix_separator;
    options.strict_autobaud = !lenient_autobaud;
    options.select_self_after_reset = select_self_after_reset;
    options.kill_acts_upstream = kill_upstream;
    options.prefix_unit_messages = prefix_unit_messages;
    options.unit.position_reply_xp = position_reply_xp;
    options.unit.signed_absolute = signed_absolute;
    options.unit.accept_backslash_overflow = overflow.backslash;
    options.unit.accept_plain_overflow = overflow.plain;
    options.unit.immediate_queue = queue;
    options.terminator = terminator;
    options.hop_delay = std::chrono::microseconds(hop_delay_us);
    auto chain = std::make_shared<centent::DaisyChain>(options, s.start());
    return sim::line_family(chain, sim::request_hooks(*chain));
  });
}
