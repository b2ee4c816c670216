#include "sim/common/line_simulator.hpp"

#include <unistd.h>

#include <exception>
#include <stdexcept>
#include <utility>

#include "sim/common/pty_port.hpp"

namespace fieldgate::sim {
namespace {

std::unique_ptr<std::FILE, int (*)(std::FILE*)> open_for_append(const std::string& path,
                                                                const std::string& what) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(nullptr, &std::fclose);
  if (path.empty()) return file;
  file.reset(std::fopen(path.c_str(), "a"));
  if (!file) throw std::runtime_error("cannot open " + what + " " + path);
  return file;
}

}  // namespace

LineSimulator::LineSimulator(std::string family, const std::string& description)
    : program_("fieldgate-sim-" + family),
      app_(description + " on a pseudo-terminal; control commands on stdin (type help).") {
  line_.name = family;
  app_.add_option("--link", link_,
                  "symlink to create for the PTY slave, e.g. /tmp/" + family + "0");
  baud_option_ = app_.add_option("--baud", baud_, "line rate for --emulate-wire");
  app_.add_flag("--emulate-wire", emulate_wire_,
                "take as long as the bytes would take on a real line at --baud");
  turnaround_option_ =
      app_.add_option("--turnaround-us", turnaround_us_)->check(CLI::NonNegativeNumber);
  set_emulated_turnaround(emulated_turnaround_);
  app_.add_option("--wire-log", wire_log_path_,
                  "append a line per request: first byte and arrival (CLOCK_MONOTONIC ns), "
                  "request, echo and reply bytes, device delay (for benchmarks)");
  app_.add_option("--journal", journal_path_,
                  "append every executed request and the device's reply to this file");
  app_.add_option("--seed", seed_, "seed for garbage replies");
  app_.add_flag("--verbose", verbose_, "log every request and reply to stderr");
}

void LineSimulator::describe_baud(std::string help, CLI::Validator rates) {
  baud_option_->description(std::move(help));
  baud_option_->check(std::move(rates));
}

void LineSimulator::set_emulated_turnaround(std::chrono::microseconds turnaround) {
  emulated_turnaround_ = turnaround;
  turnaround_option_->description("device processing time before a reply (default 0, or " +
                                  std::to_string(turnaround.count()) + " with --emulate-wire)");
}

int LineSimulator::run(int argc, char** argv,
                       const std::function<LineFamily(LineSimulator&)>& make_family) {
  try {
    app_.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app_.exit(e);
  }
  try {
    serve(make_family);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", program_.c_str(), e.what());
    return 1;
  }
  return 0;
}

void LineSimulator::serve(const std::function<LineFamily(LineSimulator&)>& make_family) {
  start_ = SimClock::now();
  LineFamily family = make_family(*this);
  device_ = std::move(family.device);
  complete_line_options();
  exchange_.emplace(std::move(family.hooks), line_, faults_);
  ControlChannel control(STDIN_FILENO, STDOUT_FILENO, faults_, std::move(family.control),
                         std::move(family.control_help));
  PtyPort port(link_);
  // Tests and scripts wait for this line before opening the port.
  std::printf("ready %s %s\n", link_.empty() ? port.slave_name().c_str() : link_.c_str(),
              port.slave_name().c_str());
  std::fflush(stdout);
  run_line_device(port, control, *exchange_);
}

void LineSimulator::complete_line_options() {
  journal_ = open_for_append(journal_path_, "journal");
  wire_log_ = open_for_append(wire_log_path_, "wire log");
  line_.wire.enabled = emulate_wire_;
  line_.wire.timing = WireTiming(baud_, line_.wire.timing.format());
  line_.wire.turnaround = turnaround_us_ >= 0 ? std::chrono::microseconds(turnaround_us_)
                          : emulate_wire_     ? emulated_turnaround_
                                              : std::chrono::microseconds(0);
  line_.seed = seed_;
  line_.verbose = verbose_;
  line_.journal = journal_.get();
  line_.wire_log = wire_log_.get();
}

}  // namespace fieldgate::sim
