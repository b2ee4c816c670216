// fieldgate-sim-whedco: Whedco CMC-0 coordinated motion controllers (several addresses on one
// RS-422/485 line, up to four axes each) on a pseudo-terminal. See README.md.

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
#include "sim/whedco/cmc_line.hpp"

namespace sim = fieldgate::sim;
namespace whedco = fieldgate::sim::whedco;

int main(int argc, char** argv) {
  CLI::App app{
      "Whedco CMC simulator: serves CMC-0 units on a pseudo-terminal; control commands on "
      "stdin (type help)."};
  std::string link;
  std::string wire_log_path;
  std::string units = "4";
  std::string axes = "WXYZ";
  std::string non_echo;
  std::string steppers;
  std::string style = "compact";
  std::uint32_t baud = 9600;
  bool emulate_wire = false;
  bool power_failure = false;
  bool initialised = false;
  std::string status_format = "decimal";
  bool fc_table_codes = false;
  bool de_answers_ed = false;
  long turnaround_us = -1;
  long position_read_us = 0;
  bool verbose = false;
  std::uint32_t seed = 1;
  app.add_option("--link", link, "symlink to create for the PTY slave, e.g. /tmp/whedco0");
  app.add_option("--wire-log", wire_log_path,
                 "append a line per request: first byte and arrival (CLOCK_MONOTONIC ns), "
                 "request, echo and reply bytes, device delay (for benchmarks)");
  app.add_option("--units", units, "CMC-0 addresses on the line, e.g. 4,5 (0-7; factory 4)");
  app.add_option("--axes", axes, "axes present: WXYZ for every unit, or ADDR:AXES,... e.g. 4:XY");
  app.add_option("--non-echo", non_echo,
                 "units in non-echo format (SW2-5): all, or addresses e.g. 5 (default: echo)");
  app.add_option("--steppers", steppers,
                 "CMC-1 stepper axes (no following error): e.g. X or 4:X; others are servos");
  app.add_option("--reply-style", style,
                 "compact (1250\\r\\n*), terminal (\\r\\n 1250\\r\\n*) or inline (the value on "
                 "the echo's line: 4RPX 1250\\r\\n*)")
      ->check(CLI::IsMember({"compact", "terminal", "inline"}));
  app.add_option("--status-format", status_format,
                 "how RS/RSa print the status word: decimal (1538), hex (0602) or binary "
                 "(0000011000000010)")
      ->check(CLI::IsMember({"decimal", "hex", "binary"}));
  app.add_flag("--fc-table-codes", fc_table_codes,
               "non-echo FC uses the FCa code table: 8 Unit Functional, 0 Power Failure, plus the "
               "axis byte (default: base x 256 + axis byte, 0 Unit Functional)");
  app.add_flag("--de-answers-ed", de_answers_ed,
               "DEn on an empty profile answers ED before the prompt (default: only the prompt)");
  app.add_flag("--initialised", initialised,
               "start already initialised: no Power Failure (default: the power-up state)");
  app.add_option("--baud", baud, "line rate for wire emulation (1200, 4800, 9600, 38400)")
      ->check(CLI::IsMember({1200u, 4800u, 9600u, 38400u, 115200u}));
  app.add_flag("--emulate-wire", emulate_wire,
               "take as long as the bytes would take on a real line at --baud");
  app.add_option("--turnaround-us", turnaround_us,
                 "command execution time before a reply (default 0, or 2000 with --emulate-wire)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--position-read-us", position_read_us,
                 "extra time of RPa/RCa/FEa (the manual: 5-10 ms)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--power-failure", power_failure,
               "start as after power-up: every fault reads Power Failure until WB (the default)");
  app.add_option("--seed", seed, "seed for garbage replies");
  app.add_flag("--verbose", verbose, "log every request and reply to stderr");
  CLI11_PARSE(app, argc, argv);

  try {
    const sim::SimTime now = sim::SimClock::now();
    whedco::LineOptions options;
    options.units = whedco::parse_units(units, axes, non_echo, steppers);
    for (auto& u : options.units) {
      u.power_failure = power_failure || !initialised;
      u.status_format = status_format == "hex"      ? whedco::StatusFormat::hex
                        : status_format == "binary" ? whedco::StatusFormat::binary
                                                    : whedco::StatusFormat::decimal;
      u.fc_table_codes = fc_table_codes;
      u.de_answers_ed = de_answers_ed;
    }
    options.style = style == "terminal" ? whedco::ReplyStyle::terminal
                    : style == "inline" ? whedco::ReplyStyle::inline_echo
                                        : whedco::ReplyStyle::compact;
    options.position_read_delay = std::chrono::microseconds(position_read_us);
    whedco::CmcLine line(options, now);

    sim::LineDeviceOptions line_options;
    line_options.wire.enabled = emulate_wire;
    line_options.wire.timing = sim::WireTiming(baud);
    line_options.wire.turnaround =
        std::chrono::microseconds(turnaround_us >= 0 ? turnaround_us : (emulate_wire ? 2000 : 0));
    line_options.terminators = "*\r\n";
    line_options.seed = seed;
    line_options.verbose = verbose;
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> wire_log(nullptr, &std::fclose);
    if (!wire_log_path.empty()) {
      wire_log.reset(std::fopen(wire_log_path.c_str(), "a"));
      if (!wire_log) throw std::runtime_error("cannot open wire log " + wire_log_path);
      line_options.wire_log = wire_log.get();
    }
    line_options.name = "whedco";

    sim::FaultInjection faults;
    sim::LineExchange exchange(
        {.frame = &whedco::CmcLine::frame,
         .respond = [&](std::string_view request,
                        sim::SimTime at) { return line.handle(request, at); },
         .echo = [&](std::string_view received) { return line.echo(received); }},
        line_options, faults);
    sim::ControlChannel control(
        STDIN_FILENO, STDOUT_FILENO, faults,
        [&](std::string_view verb, std::span<const std::string> arguments) {
          return line.control(verb, arguments, sim::SimClock::now());
        },
        whedco::CmcLine::control_help());

    sim::PtyPort port(link);
    // Tests and scripts wait for this line before opening the port.
    std::printf("ready %s %s\n", link.empty() ? port.slave_name().c_str() : link.c_str(),
                port.slave_name().c_str());
    std::fflush(stdout);
    sim::run_line_device(port, control, exchange);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fieldgate-sim-whedco: %s\n", e.what());
    return 1;
  }
  return 0;
}
