#pragma once

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "sim/common/control_channel.hpp"
#include "sim/common/line_device_loop.hpp"
#include "sim/common/wire_pacing.hpp"

namespace fieldgate::sim {

// What sets one family's simulator apart in the parts every serial-line simulator shares.
struct LineSimulatorProfile {
  std::string program;       // e.g. "fieldgate-sim-copley": the prefix of fatal errors
  std::string name;          // e.g. "copley": the prefix of verbose log lines
  std::string description;   // the head of --help
  std::string link_example;  // e.g. "/tmp/copley0"
  std::string baud_help;
  CLI::Validator baud_check;
  // --turnaround-us when it is not given and --emulate-wire is.
  std::chrono::microseconds emulated_turnaround{1000};
  FrameFormat frame_format;
  std::string terminators = "\r\n";   // LineDeviceOptions::terminators
  std::string dropped_after_request;  // LineDeviceOptions::dropped_after_request
};

// The device a family puts on the line, and its control verbs with their help text.
struct LineFamily {
  std::shared_ptr<void> device;  // kept alive as long as the line that calls its hooks
  LineDeviceHooks hooks;
  FamilyControl control;
  std::string control_help;
};

// One serial-line simulator process: the command line every family shares (--link, --baud,
// --emulate-wire, --turnaround-us, --wire-log, --journal, --seed, --verbose), the PTY, the
// control channel on stdin/stdout and the line loop. A family adds its own options to app() and
// builds its device in the callback it passes to run().
class LineSimulator {
 public:
  explicit LineSimulator(LineSimulatorProfile profile);
  LineSimulator(const LineSimulator&) = delete;
  LineSimulator& operator=(const LineSimulator&) = delete;

  CLI::App& app() { return app_; }

  // Parses the command line, builds the family's device with `make_family`, prints
  // "ready <link> <slave>" once the PTY is up and serves until `quit` or SIGINT, SIGTERM or
  // SIGHUP. Returns the process' exit status.
  int run(int argc, char** argv, const std::function<LineFamily(LineSimulator&)>& make_family);

  // For make_family: the common options as parsed, the instant the simulation starts and the
  // faults the control channel injects.
  std::uint32_t baud() const { return baud_; }
  std::uint32_t seed() const { return seed_; }
  SimTime start() const { return start_; }
  FaultInjection& faults() { return faults_; }
  // The line, for family verbs and replies on the device's own timeline; it exists once
  // make_family has returned.
  LineExchange& exchange() { return *exchange_; }

 private:
  using File = std::unique_ptr<std::FILE, int (*)(std::FILE*)>;

  void serve(const std::function<LineFamily(LineSimulator&)>& make_family);
  LineDeviceOptions line_options();

  LineSimulatorProfile profile_;
  CLI::App app_;
  std::string link_;
  std::uint32_t baud_ = 9600;
  bool emulate_wire_ = false;
  long turnaround_us_ = -1;
  std::string wire_log_path_;
  std::string journal_path_;
  std::uint32_t seed_ = 1;
  bool verbose_ = false;

  SimTime start_{};
  FaultInjection faults_;
  File journal_{nullptr, &std::fclose};
  File wire_log_{nullptr, &std::fclose};
  std::shared_ptr<void> device_;
  std::optional<LineExchange> exchange_;
};

}  // namespace fieldgate::sim
