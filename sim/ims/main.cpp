// fieldgate-sim-ims: IMS indexers in party-line mode on one RS-422 pair, served on a
// pseudo-terminal. See README.md.

#include <memory>
#include <string>

#include "sim/common/line_simulator.hpp"
#include "sim/ims/party_line.hpp"

namespace sim = fieldgate::sim;
namespace ims = fieldgate::sim::ims;

int main(int argc, char** argv) {
  sim::LineSimulator simulator("ims", "IMS indexer party-line simulator: serves named axes");
  CLI::App& app = simulator.app();
  std::string axes = "A";
  bool echo_name = false;
  bool no_completion = false;
  double overrun_above = 10'000;
  double home_at = -1000;
  std::string home_side = "minus";
  std::string result_placement = "next-line";
  std::string result_padding = "right";
  std::string result_end = "crlf";
  std::string decimals = "resolution";
  std::string echo_linefeed = "at-once";
  app.add_option("--axes", axes, "unit names on the chain, e.g. A,B,C (A-Z, a-z, [\\]^_`)");
  app.add_flag("--echo-name", echo_name, "units echo their own name before the command");
  app.add_flag("--no-completion", no_completion,
               "no CR LF after commands without a numeric result");
  app.add_option("--result-placement", result_placement,
                 "where a query's result comes: next-line (after the echoed LF) or echo-line "
                 "(on the echo's line, after the echoed command)")
      ->check(CLI::IsMember({"next-line", "echo-line"}));
  app.add_option("--result-padding", result_padding,
                 "right (\"   1000\"), space (\" 1000\") or none (\"1000\")")
      ->check(CLI::IsMember({"right", "space", "none"}));
  app.add_option("--result-end", result_end, "line end after a result: crlf or lf")
      ->check(CLI::IsMember({"crlf", "lf"}));
  app.add_option("--decimals", decimals,
                 "positions with two decimals: resolution (in variable resolution when the "
                 "fraction is not zero), always, never")
      ->check(CLI::IsMember({"resolution", "always", "never"}));
  app.add_option("--echo-linefeed", echo_linefeed,
                 "a non-query's echoed LF: at-once, or at-execution (after the completion's CR)")
      ->check(CLI::IsMember({"at-once", "at-execution"}));
  app.add_option("--overrun-above", overrun_above,
                 "steps/s above which a unit drops characters sent back to back (0 = never)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--home-at", home_at, "position of the home switch edge (power-up frame)");
  app.add_option("--home-side", home_side, "where the home switch reads high: minus or plus")
      ->check(CLI::IsMember({"minus", "plus"}));

  simulator.describe_baud("line rate for --emulate-wire (the manual documents 9600 only)",
                          CLI::Range(300u, 115200u));
  return simulator.run(argc, argv, [&](sim::LineSimulator& s) {
    ims::PartyLineOptions options;
    options.names = ims::parse_names(axes);
    options.home = {home_at, home_side == "minus"};
    options.echo_name = echo_name;
    options.completion = !no_completion;
    options.overrun_above = overrun_above;
    options.result_on_echo_line = result_placement == "echo-line";
    options.linefeed_at_execution = echo_linefeed == "at-execution";
    using Format = ims::ResultFormat;
    options.result_format.padding = result_padding == "right"   ? Format::Padding::right_aligned
                                    : result_padding == "space" ? Format::Padding::space
                                                                : Format::Padding::none;
    options.result_format.end = result_end == "lf" ? "\n" : "\r\n";
    options.result_format.decimals = decimals == "always"  ? Format::Decimals::always
                                     : decimals == "never" ? Format::Decimals::never
                                                           : Format::Decimals::variable_resolution;
    options.seed = s.seed();
    auto chain = std::make_shared<ims::PartyLine>(
        options, s.faults(), [] { return sim::SimClock::now(); }, s.start());
    return sim::line_family(chain, chain->hooks());
  });
}
