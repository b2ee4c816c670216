// fieldgate-sim-ims: IMS indexers in party-line mode on one RS-422 pair, served on a
// pseudo-terminal. See README.md.

#include <memory>
#include <string>

#include "sim/common/choice_option.hpp"
#include "sim/common/line_simulator.hpp"
#include "sim/ims/party_line.hpp"

namespace sim = fieldgate::sim;
namespace ims = fieldgate::sim::ims;

int main(int argc, char** argv) {
  sim::LineSimulator simulator("ims", "IMS indexer party-line simulator: serves named axes");
  CLI::App& app = simulator.app();
  // The command line sets the options directly; without an option, the default of the struct.
  ims::PartyLineOptions options;
  std::string axes = "A";
  bool no_completion = false;
  using Format = ims::ResultFormat;
  app.add_option("--axes", axes, "unit names on the chain, e.g. A,B,C (A-Z, a-z, [\\]^_`)");
  app.add_flag("--echo-name", options.echo_name, "units echo their own name before the command");
  app.add_flag("--no-completion", no_completion,
               "no CR LF after commands without a numeric result");
  sim::add_choice(app, "--result-placement", options.result_on_echo_line,
                  {{"next-line", false}, {"echo-line", true}},
                  "where a query's result comes: next-line (after the echoed LF) or echo-line "
                  "(on the echo's line, after the echoed command)");
  sim::add_choice(app, "--result-padding", options.result_format.padding,
                  {{"right", Format::Padding::right_aligned},
                   {"space", Format::Padding::space},
                   {"none", Format::Padding::none}},
                  "right (\"   1000\"), space (\" 1000\") or none (\"1000\")");
  sim::add_choice(app, "--result-end", options.result_format.end, {{"crlf", "\r\n"}, {"lf", "\n"}},
                  "line end after a result: crlf or lf");
  sim::add_choice(app, "--decimals", options.result_format.decimals,
                  {{"resolution", Format::Decimals::variable_resolution},
                   {"always", Format::Decimals::always},
                   {"never", Format::Decimals::never}},
                  "positions with two decimals: resolution (in variable resolution when the "
                  "fraction is not zero), always, never");
  sim::add_choice(app, "--echo-linefeed", options.linefeed_at_execution,
                  {{"at-once", false}, {"at-execution", true}},
                  "a non-query's echoed LF: at-once, or at-execution (after the completion's CR)");
  app.add_option("--overrun-above", options.overrun_above,
                 "steps/s above which a unit drops characters sent back to back (0 = never)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--home-at", options.home.edge,
                 "position of the home switch edge (power-up frame)");
  sim::add_choice(app, "--home-side", options.home.high_below, {{"minus", true}, {"plus", false}},
                  "where the home switch reads high: minus or plus");

  simulator.describe_baud("line rate for --emulate-wire (the manual documents 9600 only)",
                          CLI::Range(300u, 115200u));
  return simulator.run(argc, argv, [&](sim::LineSimulator& s) {
    options.names = ims::parse_names(axes);
    options.completion = !no_completion;
    options.seed = s.seed();
    auto chain = std::make_shared<ims::PartyLine>(
        options, s.faults(), [] { return sim::SimClock::now(); }, s.start());
    return sim::line_family(chain, chain->hooks());
  });
}
