// fieldgate-sim-ims: IMS indexers in party-line mode on one RS-422 pair, served on a
// pseudo-terminal. See README.md.

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
#include "sim/ims/party_line.hpp"

namespace sim = fieldgate::sim;
namespace ims = fieldgate::sim::ims;

int main(int argc, char** argv) {
  CLI::App app{
      "IMS indexer party-line simulator: serves named axes on a pseudo-terminal; control "
      "commands on stdin (type help)."};
  std::string link;
  std::string wire_log_path;
  std::string axes = "A";
  std::uint32_t baud = 9600;
  bool emulate_wire = false;
  long turnaround_us = -1;
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
  bool verbose = false;
  std::uint32_t seed = 1;
  app.add_option("--link", link, "symlink to create for the PTY slave, e.g. /tmp/ims0");
  app.add_option("--wire-log", wire_log_path,
                 "append a line per request: first byte and arrival (CLOCK_MONOTONIC ns), "
                 "request, echo and reply bytes, device delay (for benchmarks)");
  app.add_option("--axes", axes, "unit names on the chain, e.g. A,B,C (A-Z, a-z, [\\]^_`)");
  app.add_option("--baud", baud, "line rate for --emulate-wire (the manual documents 9600 only)")
      ->check(CLI::Range(300u, 115200u));
  app.add_flag("--emulate-wire", emulate_wire,
               "take as long as the bytes would take on a real line at the baud rate");
  app.add_option("--turnaround-us", turnaround_us,
                 "processing time before a result line (default 0, or 1000 with --emulate-wire)")
      ->check(CLI::NonNegativeNumber);
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
  app.add_option("--seed", seed, "seed for garbage replies");
  app.add_flag("--verbose", verbose, "log every request and reply to stderr");
  CLI11_PARSE(app, argc, argv);

  try {
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
    options.seed = seed;

    sim::FaultInjection faults;
    ims::PartyLine chain(
        options, faults, [] { return sim::SimClock::now(); }, sim::SimClock::now());

    sim::LineDeviceOptions line_options;
    line_options.wire.enabled = emulate_wire;
    line_options.wire.timing = sim::WireTiming(baud);
    line_options.wire.turnaround =
        std::chrono::microseconds(turnaround_us >= 0 ? turnaround_us : (emulate_wire ? 1000 : 0));
    line_options.terminators = "\r\n";
    line_options.seed = seed;
    line_options.verbose = verbose;
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> wire_log(nullptr, &std::fclose);
    if (!wire_log_path.empty()) {
      wire_log.reset(std::fopen(wire_log_path.c_str(), "a"));
      if (!wire_log) throw std::runtime_error("cannot open wire log " + wire_log_path);
      line_options.wire_log = wire_log.get();
    }
    line_options.name = "ims";

    sim::LineExchange exchange(chain.hooks(), line_options, faults);
    sim::ControlChannel control(
        STDIN_FILENO, STDOUT_FILENO, faults,
        [&](std::string_view verb, std::span<const std::string> arguments) {
          return chain.control(verb, arguments, sim::SimClock::now());
        },
        ims::PartyLine::control_help());

    sim::PtyPort port(link);
    // Tests and scripts wait for this line before opening the port.
    std::printf("ready %s %s\n", link.empty() ? port.slave_name().c_str() : link.c_str(),
                port.slave_name().c_str());
    std::fflush(stdout);
    sim::run_line_device(port, control, exchange);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fieldgate-sim-ims: %s\n", e.what());
    return 1;
  }
  return 0;
}
