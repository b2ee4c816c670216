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

LineSimulator::LineSimulator(LineSimulatorProfile profile)
    : profile_(std::move(profile)), app_(profile_.description) {
  app_.add_option("--link", link_,
                  "symlink to create for the PTY slave, e.g. " + profile_.link_example);
  app_.add_option("--baud", baud_, profile_.baud_help)->check(profile_.baud_check);
  app_.add_flag("--emulate-wire", emulate_wire_,
                "take as long as the bytes would take on a real line at --baud");
  app_.add_option("--turnaround-us", turnaround_us_,
                  "device processing time before a reply (default 0, or " +
                      std::to_string(profile_.emulated_turnaround.count()) +
                      " with --emulate-wire)")
      ->check(CLI::NonNegativeNumber);
  app_.add_option("--wire-log", wire_log_path_,
                  "append a line per request: first byte and arrival (CLOCK_MONOTONIC ns), "
                  "request, echo and reply bytes, device delay (for benchmarks)");
  app_.add_option("--journal", journal_path_,
                  "append every executed request and the device's reply to this file");
  app_.add_option("--seed", seed_, "seed for garbage replies");
  app_.add_flag("--verbose", verbose_, "log every request and reply to stderr");
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
    std::fprintf(stderr, "%s: %s\n", profile_.program.c_str(), e.what());
    return 1;
  }
  return 0;
}

void LineSimulator::serve(const std::function<LineFamily(LineSimulator&)>& make_family) {
  start_ = SimClock::now();
  LineFamily family = make_family(*this);
  device_ = std::move(family.device);
  journal_ = open_for_append(journal_path_, "journal");
  wire_log_ = open_for_append(wire_log_path_, "wire log");
  exchange_.emplace(std::move(family.hooks), line_options(), faults_);
  ControlChannel control(STDIN_FILENO, STDOUT_FILENO, faults_, std::move(family.control),
                         std::move(family.control_help));
  PtyPort port(link_);
  // Tests and scripts wait for this line before opening the port.
  std::printf("ready %s %s\n", link_.empty() ? port.slave_name().c_str() : link_.c_str(),
              port.slave_name().c_str());
  std::fflush(stdout);
  run_line_device(port, control, *exchange_);
}

LineDeviceOptions LineSimulator::line_options() {
  LineDeviceOptions options;
  options.wire.enabled = emulate_wire_;
  options.wire.timing = WireTiming(baud_, profile_.frame_format);
  options.wire.turnaround = turnaround_us_ >= 0 ? std::chrono::microseconds(turnaround_us_)
                            : emulate_wire_     ? profile_.emulated_turnaround
                                                : std::chrono::microseconds(0);
  options.terminators = profile_.terminators;
  options.dropped_after_request = profile_.dropped_after_request;
  options.seed = seed_;
  options.verbose = verbose_;
  options.journal = journal_.get();
  options.wire_log = wire_log_.get();
  options.name = profile_.name;
  return options;
}

}  // namespace fieldgate::sim
