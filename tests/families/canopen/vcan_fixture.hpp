// Pieces the vcan tests share: the CANopen simulator and candump (the foreign observer) as
// child processes on vcan0, a raw socket for frames the test sends itself, and `ip` commands.
// These tests run inside scripts/vcan-run; without vcan0 they fail, they never skip.
#pragma once

#include <gtest/gtest.h>
#include <linux/can.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "drivers/transport/can_frame.hpp"
#include "harness.hpp"

namespace fieldgate::test {

using namespace std::chrono_literals;

inline const char* can_interface() {
  const char* i = std::getenv("FIELDGATE_VCAN_IF");
  return i && *i ? i : "vcan0";
}

// Fails the test (never skips) when the interface is missing: run through scripts/vcan-run.
inline ::testing::AssertionResult vcan_present() {
  if (::if_nametoindex(can_interface()) != 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "no interface " << can_interface()
         << ": run this test through scripts/vcan-run (host vcan or User-Mode Linux)";
}

// Whether a suite's shared set-up (SetUpTestSuite) made `shared` and left no error in it.
template <class Shared>
::testing::AssertionResult suite_ready(const Shared* shared) {
  if (!shared) return ::testing::AssertionFailure() << "the suite's set-up did not run";
  if (!shared->error.empty()) return ::testing::AssertionFailure() << shared->error;
  return ::testing::AssertionSuccess();
}

// Runs a shell command (ip link ...), returning its exit status.
inline int shell(const std::string& command) {
  return std::system(command.c_str());
}

// Sends one frame (data, remote or error frame) from a socket of the test's own.
inline bool raw_send(const CanFrame& frame) {
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) return false;
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(::if_nametoindex(can_interface()));
  bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  can_frame raw{};
  raw.can_id = frame.id | (frame.rtr ? CAN_RTR_FLAG : 0u) | (frame.error ? CAN_ERR_FLAG : 0u);
  raw.len = frame.len;
  std::memcpy(raw.data, frame.data.data(), frame.len);
  ok = ok && ::write(fd, &raw, sizeof raw) == static_cast<ssize_t>(sizeof raw);
  ::close(fd);
  return ok;
}

// candump -L on the interface: every frame as "ID#DATA", error frames included.
class Candump {
 public:
  explicit Candump(const ScratchDir& dir)
      : log_(dir / "candump.log"),
        process_(std::vector<std::string>{"/usr/bin/candump", "-D", "-L",
                                          std::string(can_interface()) + ",0:0,#FFFFFFFF"},
                 log_) {}

  // Sends probe frames until candump logs one, so nothing the test does later is missed.
  bool wait_listening() {
    return wait_until(
        [&] {
          raw_send(*parse_frame("7FF#01"));
          return count("7FF#01") > 0;
        },
        20s);
  }
  std::vector<std::string> frames() const {
    std::vector<std::string> out;
    std::ifstream in(log_);
    std::string line;
    while (std::getline(in, line)) {
      const auto space = line.rfind(' ');
      out.push_back(space == std::string::npos ? line : line.substr(space + 1));
    }
    return out;
  }
  std::size_t size() const { return frames().size(); }
  std::size_t count(const std::string& pattern, std::size_t from = 0) const {
    const std::regex re(pattern);
    const auto all = frames();
    std::size_t n = 0;
    for (std::size_t i = from; i < all.size(); ++i) n += std::regex_match(all[i], re) ? 1 : 0;
    return n;
  }
  std::string text(std::size_t from = 0) const {
    std::string s;
    const auto all = frames();
    for (std::size_t i = from; i < all.size(); ++i) s += all[i] + "\n";
    return s;
  }
  ChildProcess& process() { return process_; }

 private:
  std::filesystem::path log_;
  ChildProcess process_;
};

// fieldgate-sim-canopen with line commands on its stdin (power-off ID, fault ID CODE, ...). Its
// nodes power up as CiA 301 devices ship (0x1017 = 0, no heartbeat) unless extra says otherwise.
class CanopenSim {
 public:
  CanopenSim(const ScratchDir& dir, const std::string& nodes, const std::string& name = "sim",
             std::vector<std::string> extra = {}) {
    std::vector<std::string> argv{FIELDGATE_SIM_CANOPEN, "--interface", can_interface(), "--nodes",
                                  nodes};
    argv.insert(argv.end(), extra.begin(), extra.end());
    process_ = std::make_unique<ChildProcess>(argv, dir / (name + ".log"));
  }
  bool wait_ready() {
    return wait_until([&] { return log().find("ready ") != std::string::npos || !running(); },
                      20s) &&
           running();
  }
  void command(const std::string& line) { process_->send_line(line); }
  std::string log() const { return process_->log(); }
  bool running() { return process_->running(); }
  ChildProcess& process() { return *process_; }  // for control_line (done_property.hpp)

 private:
  std::unique_ptr<ChildProcess> process_;
};

// What each vcan suite starts first, in its scratch folder: candump, listening, then the CANopen
// simulator with `nodes`. `error` says what failed; the suite's tests fail on it (suite_ready).
struct VcanSuite {
  ScratchDir dir;
  std::unique_ptr<Candump> candump;
  std::unique_ptr<CanopenSim> sim;
  std::string error;

  bool start_candump_and_sim(const std::string& nodes) {
    candump = std::make_unique<Candump>(dir);
    if (!candump->wait_listening()) {
      error = "candump does not log frames";
      return false;
    }
    sim = std::make_unique<CanopenSim>(dir, nodes);
    if (!sim->wait_ready()) {
      error = "simulator did not start: " + sim->log();
      return false;
    }
    return true;
  }
};

// The start of a suite's SetUpTestSuite: without the interface nothing (its tests fail on that),
// else `shared` made, with candump and the simulator with `nodes` started. False when the
// suite's set-up cannot go on.
template <class Suite>
bool begin_suite(Suite*& shared, const std::string& nodes) {
  if (!vcan_present()) return false;
  shared = new Suite;
  return shared->start_candump_and_sim(nodes);
}

}  // namespace fieldgate::test
