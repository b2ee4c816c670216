#pragma once

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "sim/common/control_channel.hpp"
#include "sim/common/line_device_loop.hpp"
#include "sim/common/wire_pacing.hpp"

namespace fieldgate::sim {

// The device a family puts on the line, and its control verbs with their help text.
struct LineFamily {
  std::shared_ptr<void> device;  // kept alive as long as the line that calls its hooks
  LineDeviceHooks hooks;
  FamilyControl control;
  std::string control_help;
};

// The usual family: `device` on the line through `hooks`, its verbs taken by
// device->control(verb, arguments, now) and documented by Device::control_help().
template <class Device>
LineFamily line_family(std::shared_ptr<Device> device, LineDeviceHooks hooks) {
  LineFamily family;
  family.hooks = std::move(hooks);
  family.control = [d = device.get()](std::string_view verb,
                                      std::span<const std::string> arguments) {
    return d->control(verb, arguments, SimClock::now());
  };
  family.control_help = Device::control_help();
  family.device = std::move(device);
  return family;
}

// Hooks of a device that frames requests with Device::frame and answers each with handle().
template <class Device>
LineDeviceHooks request_hooks(Device& device) {
  LineDeviceHooks hooks;
  hooks.frame = &Device::frame;
  hooks.respond = [&device](std::string_view request, SimTime at) {
    return device.handle(request, at);
  };
  return hooks;
}

// One serial-line simulator process, fieldgate-sim-<family>: the command line every family
// shares (--link, --baud, --emulate-wire, --turnaround-us, --wire-log, --journal, --seed,
// --verbose), the PTY, the control channel on stdin/stdout and the line loop. A family adds its
// own options to app(), its line settings to line(), and builds its device in the callback it
// passes to run().
class LineSimulator {
 public:
  // `description`: "<device> simulator: serves <what>", the head of --help.
  LineSimulator(std::string family, const std::string& description);
  LineSimulator(const LineSimulator&) = delete;
  LineSimulator& operator=(const LineSimulator&) = delete;

  CLI::App& app() { return app_; }
  // --baud: what it means to the family and the rates it takes (default 9600).
  void describe_baud(std::string help, CLI::Validator rates);
  // --turnaround-us when it is not given and --emulate-wire is (default 1 ms).
  void set_emulated_turnaround(std::chrono::microseconds turnaround);
  // The family's line settings (terminators, dropped_after_request, name, frame format); the
  // command line fills in the rest.
  LineDeviceOptions& line() { return line_; }

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
  void complete_line_options();

  std::string program_;
  CLI::App app_;
  LineDeviceOptions line_;
  CLI::Option* baud_option_ = nullptr;
  CLI::Option* turnaround_option_ = nullptr;
  std::chrono::microseconds emulated_turnaround_{1000};
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
