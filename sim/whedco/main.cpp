// fieldgate-sim-whedco: Whedco CMC-0 coordinated motion controllers (several addresses on one
// RS-422/485 line, up to four axes each) on a pseudo-terminal. See README.md.

#include <memory>
#include <string>

#include "sim/common/choice_option.hpp"
#include "sim/common/duration_option.hpp"
#include "sim/common/line_simulator.hpp"
#include "sim/whedco/cmc_line.hpp"

namespace sim = fieldgate::sim;
namespace whedco = fieldgate::sim::whedco;

int main(int argc, char** argv) {
  sim::LineSimulator simulator("whedco", "Whedco CMC simulator: serves CMC-0 units");
  simulator.set_emulated_turnaround(std::chrono::microseconds(2000));
  simulator.line().terminators = "*\r\n";
  CLI::App& app = simulator.app();
  std::string units = "4";
  std::string axes = "WXYZ";
  std::string non_echo;
  std::string steppers;
  // The command line sets these options directly; without an option, the default of the struct.
  whedco::LineOptions options;
  bool power_failure = false;
  bool initialised = false;
  auto status_format = whedco::StatusFormat::decimal;
  bool fc_table_codes = false;
  bool de_answers_ed = false;
  app.add_option("--units", units, "CMC-0 addresses on the line, e.g. 4,5 (0-7; factory 4)");
  app.add_option("--axes", axes, "axes present: WXYZ for every unit, or ADDR:AXES,... e.g. 4:XY");
  app.add_option("--non-echo", non_echo,
                 "units in non-echo format (SW2-5): all, or addresses e.g. 5 (default: echo)");
  app.add_option("--steppers", steppers,
                 "CMC-1 stepper axes (no following error): e.g. X or 4:X; others are servos");
  sim::add_choice(app, "--reply-style", options.style,
                  {{"compact", whedco::ReplyStyle::compact},
                   {"terminal", whedco::ReplyStyle::terminal},
                   {"inline", whedco::ReplyStyle::inline_echo}},
                  "compact (1250\\r\\n*), terminal (\\r\\n 1250\\r\\n*) or inline (the value on "
                  "the echo's line: 4RPX 1250\\r\\n*)");
  sim::add_choice(app, "--status-format", status_format,
                  {{"decimal", whedco::StatusFormat::decimal},
                   {"hex", whedco::StatusFormat::hex},
                   {"binary", whedco::StatusFormat::binary}},
                  "how RS/RSa print the status word: decimal (1538), hex (0602) or binary "
                  "(0000011000000010)");
  app.add_flag("--fc-table-codes", fc_table_codes,
               "non-echo FC uses the FCa code table: 8 Unit Functional, 0 Power Failure, plus the "
               "axis byte (default: base x 256 + axis byte, 0 Unit Functional)");
  app.add_flag("--de-answers-ed", de_answers_ed,
               "DEn on an empty profile answers ED before the prompt (default: only the prompt)");
  app.add_flag("--initialised", initialised,
               "start already initialised: no Power Failure (default: the power-up state)");
  sim::add_duration(app, "--position-read-us", options.position_read_delay,
                    "extra time of RPa/RCa/FEa (the manual: 5-10 ms)");
  app.add_flag("--power-failure", power_failure,
               "start as after power-up: every fault reads Power Failure until WB (the default)");

  simulator.describe_baud("line rate for wire emulation (1200, 4800, 9600, 38400)",
                          CLI::IsMember({1200u, 4800u, 9600u, 38400u, 115200u}));
  return simulator.run(argc, argv, [&](sim::LineSimulator& s) {
    options.units = whedco::parse_units(units, axes, non_echo, steppers);
    for (auto& u : options.units) {
      u.power_failure = power_failure || !initialised;
      u.status_format = status_format;
      u.fc_table_codes = fc_table_codes;
      u.de_answers_ed = de_answers_ed;
    }
    auto line = std::make_shared<whedco::CmcLine>(options, s.start());
    sim::LineDeviceHooks hooks = sim::request_hooks(*line);
    hooks.echo = [&unit = *line](std::string_view received) { return unit.echo(received); };
    return sim::line_family(line, std::move(hooks));
  });
}
