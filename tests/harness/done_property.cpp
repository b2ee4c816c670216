#include "done_property.hpp"

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <latch>
#include <memory>
#include <ostream>
#include <random>
#include <regex>
#include <sstream>
#include <thread>
#include <utility>

#include "fault_property.hpp"

namespace fieldgate::test {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

std::ostream& operator<<(std::ostream& os, const DoneCounts& c) {
  os << "commands " << c.commands << ", simultaneous " << c.simultaneous << ", resets " << c.resets
     << ", interrupted " << c.interrupted << ", done " << c.dones << ", aborted " << c.aborted
     << ", hung " << c.hung << ", failed {";
  const char* sep = "";
  for (const auto& [code, n] : c.failures) {
    os << sep << std::hex << "0x" << code << std::dec << ": " << n;
    sep = ", ";
  }
  os << "}, refused {";
  sep = "";
  for (const auto& [code, n] : c.refused) {
    os << sep << std::hex << "0x" << code << std::dec << ": " << n;
    sep = ", ";
  }
  os << "}, fresh " << c.fresh_ended << " of " << c.fresh_commands << " ended (" << c.fresh_refused
     << " refused 0x03), false done " << c.false_dones;
  return os;
}

unsigned done_seed(unsigned fallback) {
  const char* seed = std::getenv("FIELDGATE_DONE_SEED");
  return seed && *seed ? static_cast<unsigned>(std::strtoul(seed, nullptr, 10)) : fallback;
}

std::optional<std::string> control_line(ChildProcess& sim, const std::string& line,
                                        const std::string& tag) {
  auto answer = control_answer(sim, line, tag, 5s);
  if (!answer) return std::nullopt;
  return answer->substr(0, answer->find('\n'));
}

std::optional<std::string> unix_socket_request(const std::string& path, const std::string& line) {
  const int s = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (s < 0) return std::nullopt;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
  timeval timeout{5, 0};
  ::setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  std::optional<std::string> answer;
  if (::connect(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) {
    const std::string request = line + "\n";
    if (::send(s, request.data(), request.size(), MSG_NOSIGNAL) ==
        static_cast<ssize_t>(request.size())) {
      std::string got;
      char buf[4096];
      ssize_t n;
      while (got.find('\n') == std::string::npos && (n = ::recv(s, buf, sizeof buf, 0)) > 0)
        got.append(buf, static_cast<std::size_t>(n));
      if (got.find('\n') != std::string::npos) answer = got.substr(0, got.find('\n'));
    }
  }
  ::close(s);
  return answer;
}

std::optional<int64_t> field_after(const std::string& text, const std::string& key) {
  const auto at = text.find(key);
  if (at == std::string::npos) return std::nullopt;
  const char* start = text.c_str() + at + key.size();
  char* end = nullptr;
  const double v = std::strtod(start, &end);
  if (end == start) return std::nullopt;
  return static_cast<int64_t>(std::llround(v));
}

namespace {

// Input registers 7-10: sequence_echo, command_status, command_echo, command_error.
constexpr int kSequenceEcho = 7, kActualPosition = 0, kTargetRegister = 0, kVelocity = 2,
              kAcceleration = 4, kDeceleration = 6, kCommandCode = 8;
// The input page: status word, PLCopen state, command status.
constexpr int kStatusWord = 4, kState = 5, kCommandStatus = 8, kErrorStop = 6, kErrorBit = 1 << 4;

const char* command_name(uint16_t code) {
  switch (code) {
    case kPowerOn:
      return "power_on";
    case kHome:
      return "home";
    case kMoveAbsolute:
      return "move_absolute";
    case kMoveRelative:
      return "move_relative";
    case kResetCommand:
      return "reset";
    default:
      return "command";
  }
}

struct Command {
  int unit = 0;
  uint16_t code = 0;
  uint16_t sequence = 0;
  std::optional<int64_t> target;  // where the device must stand when the command reads done
  std::string what;               // for the report
  int exception = 0;              // the answer to the command write
  bool taken = false;             // sequence_echo showed it
  bool interrupted = false;       // a reset went in while it ran short of its target
  bool fresh = false;             // the velocity register was never written
  bool ended = false;
  int status = 0;
  uint16_t error = 0;
  Clock::time_point sent{}, deadline{};
};

class DoneRun {
 public:
  DoneRun(int port, unsigned seed, const DoneProperty& property)
      : port_(port), property_(property), random_(seed), seed_(seed) {
    client_ = connect();
    for (const auto& a : property_.axes) clients_[a.unit] = connect();
  }

  const DoneCounts& counts() const { return counts_; }

  // FIELDGATE_DONE_VERBOSE=1: every command, reset and outcome on stdout (to replay a case).
  void trace(const std::string& line) const {
    if (!verbose_) return;
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - start_);
    std::cout << "[" << ms.count() << " ms] round " << round_ << ": " << line << std::endl;
  }

  void go() {
    fresh_axes();
    for (const auto& a : property_.axes) {
      if (property_.velocity != 0) client_->write_i32(a.unit, kVelocity, property_.velocity);
      if (property_.acceleration != 0) {
        client_->write_i32(a.unit, kAcceleration, property_.acceleration);
        client_->write_i32(a.unit, kDeceleration, property_.acceleration);
      }
    }
    std::vector<int> kinds;
    for (int i = 0; i < property_.rounds; ++i) kinds.push_back(i % 3);
    std::shuffle(kinds.begin(), kinds.end(), random_);
    for (std::size_t round = 0; round < kinds.size() && !stuck_; ++round) {
      round_ = static_cast<int>(round);
      if (kinds[round] == 0) simultaneous_round();
      if (kinds[round] == 1) reset_round();
      if (kinds[round] == 2) single_round();
      if (::testing::Test::HasFatalFailure()) break;
    }
  }

 private:
  std::unique_ptr<ModbusClient> connect() {
    return std::make_unique<ModbusClient>("127.0.0.1", port_);
  }

  uint16_t next_sequence(int unit) {
    uint16_t& s = sequences_[unit];
    s = static_cast<uint16_t>(s == 65535 ? 1 : s + 1);
    return s;
  }

  // Input registers 7-10 of a unit; empty when not answered.
  std::vector<uint16_t> command_registers(int unit) {
    auto r = client_->read_input(unit, kSequenceEcho, 4);
    if (!answered(r.exception)) client_ = connect();
    return r.ok() ? r.values : std::vector<uint16_t>{};
  }

  bool page_readable(int unit) { return client_->read_input(unit, 0, 12).ok(); }

  std::optional<int64_t> device(int unit) { return property_.device_position(unit); }

  // A target at least `travel` from `from` and at least min_travel from 0, in range.
  int64_t draw_target(int64_t from, int64_t travel) {
    std::uniform_int_distribution<int64_t> in_range(property_.min_target, property_.max_target);
    for (int i = 0; i < 200; ++i) {
      const int64_t t = in_range(random_);
      if (std::llabs(t - from) >= travel && std::llabs(t) >= property_.min_travel) return t;
    }
    // The farther end of the range, never within min_travel of 0.
    int64_t low = property_.min_target, high = property_.max_target;
    if (low >= 0 && low < property_.min_travel) low = property_.min_travel;
    if (high <= 0 && high > -property_.min_travel) high = -property_.min_travel;
    return from - low > high - from ? low : high;
  }

  // A move of at least `travel` on a standing axis, its setpoint written; the command is sent
  // later.
  Command prepare_move(int unit, int64_t travel, bool fresh = false) {
    Command c;
    c.unit = unit;
    c.fresh = fresh;
    // Where the device stands still: a relative move's target counts from there. (An axis whose
    // home failed at the gateway may still be searching.)
    std::optional<int64_t> standing;
    wait_until(
        [&] {
          const auto before = device(unit);
          std::this_thread::sleep_for(100ms);
          standing = device(unit);
          return before && standing && *before == *standing;
        },
        10s);
    const int64_t from = standing ? *standing : client_->read_input_i32(unit, 0).value_or(0);
    const int64_t target = draw_target(from, travel);
    c.code = random_() % 2 && std::llabs(target - from) <= property_.max_distance ? kMoveRelative
                                                                                  : kMoveAbsolute;
    const int64_t setpoint = c.code == kMoveAbsolute ? target : target - from;
    c.target = target;
    c.what = std::string(command_name(c.code)) + " " + std::to_string(setpoint) + " from " +
             std::to_string(from) + " (target " + std::to_string(target) + ")";
    auto w = client_->write_i32(unit, kTargetRegister, static_cast<int32_t>(setpoint));
    if (!answered(w.exception)) client_ = connect();
    EXPECT_TRUE(w.ok()) << "unit " << unit << ": setpoint write answered " << w.exception;
    return c;
  }

  Command prepare(int unit, uint16_t code, std::optional<int64_t> target = std::nullopt,
                  bool fresh = false) {
    Command c;
    c.unit = unit;
    c.code = code;
    c.target = target;
    c.fresh = fresh;
    c.what = command_name(code);
    return c;
  }

  // Writes the command and sequence number (holding 8-9) on `client`.
  void write_command(Command& c, std::unique_ptr<ModbusClient>& client) {
    c.sent = Clock::now();
    c.exception = client->write(c.unit, kCommandCode, {c.code, c.sequence}).exception;
    if (!answered(c.exception)) client = connect();
  }

  // Sends the commands: one on the test's connection, several each on its axis's own
  // connection, released together. Then whether the gateway took each.
  void send(std::vector<Command>& commands, bool count_simultaneous = true) {
    for (auto& c : commands) c.sequence = next_sequence(c.unit);
    if (commands.size() == 1) {
      write_command(commands[0], client_);
    } else {
      std::latch go(static_cast<std::ptrdiff_t>(commands.size()));
      std::vector<std::thread> threads;
      for (auto& c : commands)
        threads.emplace_back([&, client = &clients_.at(c.unit)] {
          go.arrive_and_wait();
          write_command(c, *client);
        });
      for (auto& t : threads) t.join();
      if (count_simultaneous) counts_.simultaneous += static_cast<int>(commands.size());
    }
    for (auto& c : commands) {
      c.deadline = Clock::now() + (c.fresh ? property_.fresh_timeout : property_.command_timeout);
      // A taken command shows in sequence_echo before its write is answered; a write that got
      // no answer may still have been taken.
      c.taken = wait_until(
          [&] {
            const auto r = command_registers(c.unit);
            return !r.empty() && r[0] == c.sequence;
          },
          c.exception == 0 || !answered(c.exception) || c.exception == 0x0B ? 3s : 100ms);
      trace("unit " + std::to_string(c.unit) + " seq " + std::to_string(c.sequence) + " " + c.what +
            (c.fresh ? " (velocity never written)" : "") + ": answered " +
            std::to_string(c.exception) + (c.taken ? ", taken" : ", not taken"));
      if (c.taken) {
        ++counts_.commands;
      } else {
        ++counts_.refused[c.exception];
        c.ended = true;
      }
      if (c.fresh) {
        ++counts_.fresh_commands;
        if (!c.taken && c.exception == 0x03) {
          ++counts_.fresh_refused;
          ++counts_.fresh_ended;
        }
      }
      // Each command owns its values: a later write of the target register changes nothing.
      if (c.taken && c.target && random_() % 2)
        client_->write_i32(c.unit, kTargetRegister, static_cast<int32_t>(*c.target + 777));
    }
  }

  // Reads a running command's status; judges it once it ended.
  void poll(Command& c) {
    if (c.ended) return;
    const auto r = command_registers(c.unit);
    if (r.empty()) return;
    if (r[0] != c.sequence) {
      ADD_FAILURE() << "unit " << c.unit << " seq " << c.sequence << " " << c.what
                    << ": sequence_echo became " << r[0] << " with no newer command";
      c.ended = true;
      return;
    }
    if (r[1] == kBusy) return;
    c.ended = true;
    c.status = r[1];
    c.error = r[3];
    judge(c);
  }

  void judge(const Command& c) {
    trace("unit " + std::to_string(c.unit) + " seq " + std::to_string(c.sequence) +
          " ended: status " + std::to_string(c.status) + " error " + std::to_string(c.error));
    if (c.fresh) ++counts_.fresh_ended;
    if (c.status == kAborted) ++counts_.aborted;
    if (c.status == kError) ++counts_.failures[c.error];
    if (c.status != kDone) return;
    ++counts_.dones;
    const auto served = client_->read_input_i32(c.unit, kActualPosition);
    std::optional<int64_t> at;
    bool arrived = !c.target.has_value();
    if (c.target) {
      // Standing at the target: the device's own position now, and again a moment later.
      at = device(c.unit);
      if (at && std::llabs(*at - *c.target) <= property_.tolerance) {
        std::this_thread::sleep_for(30ms);
        at = device(c.unit);
        arrived = at && std::llabs(*at - *c.target) <= property_.tolerance;
      }
    }
    if (arrived && !c.interrupted) return;
    ++counts_.false_dones;
    std::ostringstream why;
    why << "seed " << seed_ << " round " << round_ << ": unit " << c.unit << " seq " << c.sequence
        << " " << c.what << " read done; served position "
        << (served ? std::to_string(*served) : "unreadable") << ", the device's "
        << (at ? std::to_string(*at) : "unknown")
        << (c.interrupted ? "; a reset went in while it ran short of its target" : "");
    counts_.false_done_cases.push_back(why.str());
    ADD_FAILURE() << "false done: " << why.str();
  }

  // Polls the commands until each ended or passed its deadline (a hung command: a failure).
  void wait_all(std::vector<Command>& commands) {
    for (;;) {
      bool running = false;
      for (auto& c : commands) {
        poll(c);
        if (c.ended) continue;
        if (Clock::now() > c.deadline) {
          c.ended = true;
          ++counts_.hung;
          stuck_ = true;  // the rest of the run would only wait the same
          ADD_FAILURE() << "seed " << seed_ << " round " << round_ << ": unit " << c.unit << " seq "
                        << c.sequence << " " << c.what
                        << (c.fresh ? " (velocity never written)" : "")
                        << " still busy after its bounded wait";
          continue;
        }
        running = true;
      }
      if (!running) return;
      std::this_thread::sleep_for(20ms);
    }
  }

  void run_alone(Command c) {
    std::vector<Command> one{std::move(c)};
    send(one);
    wait_all(one);
  }

  // Out of ErrorStop (a reset command), powered where the model needs it, the page readable.
  void recover(int unit) {
    if (stuck_) return;
    if (!wait_until([&] { return page_readable(unit); }, 15s)) {
      ADD_FAILURE() << "seed " << seed_ << " round " << round_ << ": unit " << unit
                    << " serves no page 15 s after its commands ended";
      stuck_ = true;
      return;
    }
    const auto page = client_->read_input(unit, 0, 12);
    if (page.ok() && (page.values[kCommandStatus] == kError || page.values[kState] == kErrorStop ||
                      (page.values[kStatusWord] & kErrorBit)))
      run_alone(prepare(unit, kResetCommand));
    if (property_.power_on) {
      const auto status = client_->read_input(unit, kStatusWord, 1);
      if (!status.ok() || (status.values[0] & 1) == 0) run_alone(prepare(unit, kPowerOn));
    }
  }

  // Home, then a move, on every axis at once before its velocity register was ever written:
  // each ends (done, error, or refused with 0x03) within fresh_timeout.
  void fresh_axes() {
    for (const auto& a : property_.axes) {
      ASSERT_TRUE(wait_until([&] { return page_readable(a.unit); }, 20s))
          << "unit " << a.unit << " never served its page";
      if (property_.power_on) run_alone(prepare(a.unit, kPowerOn));
    }
    std::vector<Command> homes;
    for (const auto& a : property_.axes)
      homes.push_back(prepare(a.unit, kHome, property_.home_position, true));
    send(homes, false);
    wait_all(homes);
    for (const auto& a : property_.axes) recover(a.unit);
    if (!property_.fresh_move || stuck_) return;
    std::vector<Command> moves;
    for (const auto& a : property_.axes)
      moves.push_back(prepare_move(a.unit, property_.min_travel, true));
    send(moves, false);
    wait_all(moves);
    for (const auto& a : property_.axes) recover(a.unit);
  }

  std::vector<int> group_of_node(int node) const {
    std::vector<int> units;
    for (const auto& a : property_.axes)
      if (a.node == node) units.push_back(a.unit);
    return units;
  }

  // Every axis of a node at once; with only single-axis nodes, every axis of the plant.
  void simultaneous_round() {
    std::vector<std::vector<int>> groups;
    for (const auto& a : property_.axes) {
      auto g = group_of_node(a.node);
      if (g.size() > 1 && std::find(groups.begin(), groups.end(), g) == groups.end())
        groups.push_back(g);
    }
    if (groups.empty()) {
      groups.emplace_back();
      for (const auto& a : property_.axes) groups.back().push_back(a.unit);
    }
    const auto& units = groups[random_() % groups.size()];
    std::vector<Command> commands;
    for (int unit : units) commands.push_back(prepare_move(unit, property_.min_travel));
    send(commands);
    wait_all(commands);
    for (int unit : units) recover(unit);
  }

  void single_round() {
    const int unit = property_.axes[random_() % property_.axes.size()].unit;
    std::vector<Command> commands{prepare_move(unit, property_.min_travel)};
    send(commands);
    wait_all(commands);
    recover(unit);
  }

  // Long moves on one controller (one axis, or all of them at once), a reset while they run.
  void reset_round() {
    std::vector<int> controllers;
    for (const auto& a : property_.axes)
      if (a.controller >= 0 &&
          std::find(controllers.begin(), controllers.end(), a.controller) == controllers.end())
        controllers.push_back(a.controller);
    if (controllers.empty()) return;
    const int controller = controllers[random_() % controllers.size()];
    std::vector<int> units;
    for (const auto& a : property_.axes)
      if (a.controller == controller) units.push_back(a.unit);
    // Every other reset round interrupts one axis; the others interrupt every axis of the
    // controller at once, some of whose commands may still wait for the node's turn.
    if (units.size() > 1 && counts_.resets % 2 == 1) units = {units[random_() % units.size()]};
    std::vector<Command> commands;
    for (int unit : units) commands.push_back(prepare_move(unit, property_.long_travel));
    send(commands);
    std::uniform_int_distribution<long> delay(property_.reset_after_min.count(),
                                              property_.reset_after_max.count());
    std::this_thread::sleep_for(std::chrono::milliseconds(delay(random_)));
    for (auto& c : commands) poll(c);
    // Short of its target by a twentieth of the trip at least: it cannot arrive before the
    // reset goes in, a few milliseconds later.
    std::vector<Command*> running;
    for (auto& c : commands) {
      if (c.ended || !c.target) continue;
      const auto at = device(c.unit);
      trace("unit " + std::to_string(c.unit) + " before the reset: the device at " +
            (at ? std::to_string(*at) : "unknown") + ", target " + std::to_string(*c.target));
      if (at && std::llabs(*at - *c.target) > property_.long_travel / 20) running.push_back(&c);
    }
    trace("reset of controller " + std::to_string(controller) + ", " +
          std::to_string(running.size()) + " command(s) short of their targets");
    property_.reset(controller);
    ++counts_.resets;
    for (Command* c : running) {
      c->interrupted = true;
      ++counts_.interrupted;
    }
    wait_all(commands);
    for (Command* c : running) interrupted_outcomes_.push_back({c->status, c->error});
    std::vector<int> all;
    for (const auto& a : property_.axes)
      if (a.controller == controller) all.push_back(a.unit);
    for (int unit : all) recover(unit);
  }

 public:
  // command_status and command_error of each interrupted command
  std::vector<std::pair<int, uint16_t>> interrupted_outcomes_;

 private:
  int port_;
  const DoneProperty& property_;
  std::mt19937 random_;
  unsigned seed_;
  int round_ = -1;
  bool stuck_ = false;  // a command hung or a unit never came back: the run stops there
  bool verbose_ = std::getenv("FIELDGATE_DONE_VERBOSE") != nullptr;
  Clock::time_point start_ = Clock::now();
  std::unique_ptr<ModbusClient> client_;
  std::map<int, std::unique_ptr<ModbusClient>> clients_;  // one per axis, for simultaneous sends
  std::map<int, uint16_t> sequences_;
  DoneCounts counts_;
};

}  // namespace

DoneCounts run_done_property(Plant& plant, unsigned seed, const DoneProperty& property) {
  return run_done_property(plant.port(), plant.daemon(), seed, property);
}

DoneCounts run_done_property(int port, ChildProcess& daemon, unsigned seed,
                             const DoneProperty& property) {
  DoneRun run(port, seed, property);
  bool finished = true;
  try {
    run.go();
  } catch (const std::exception& e) {
    // A connection refused: the daemon is gone (its log follows the failure).
    ADD_FAILURE() << e.what() << "; the daemon "
                  << (daemon.running() ? "still runs" : "is no longer running");
    finished = false;
  }
  const DoneCounts& counts = run.counts();
  std::cout << "done property, seed " << seed << (finished ? "" : " (cut short)") << ": " << counts
            << "\n";
  ::testing::Test::RecordProperty("done_property", ::testing::PrintToString(counts));
  if (std::getenv("FIELDGATE_DONE_VERBOSE") != nullptr)
    std::cout << "--- daemon log ---\n" << daemon.log();
  if (!finished) return counts;

  EXPECT_EQ(counts.false_dones, 0);
  EXPECT_EQ(counts.hung, 0);
  // The velocity never written: every such command ended, none hung until a timeout.
  EXPECT_EQ(counts.fresh_ended, counts.fresh_commands);
  EXPECT_GT(counts.fresh_commands, 0);
  // Not vacuous.
  EXPECT_GT(counts.simultaneous, 0);
  EXPECT_GT(counts.resets, 0);
  EXPECT_GT(counts.interrupted, 0) << "no reset went in while a move ran";
  EXPECT_GT(counts.dones, 0);
  // An interrupted move ends failed (or aborted), never done nor busy.
  // Failed with the reset's own code (docs/axis-profile.md), which tells the PLC why.
  int interrupted_failed = 0;
  for (const auto& [status, error] : run.interrupted_outcomes_) {
    if (status != kError) continue;
    ++interrupted_failed;
    if (property.reset_visible) {
      EXPECT_EQ(error, kControllerReset)
          << "a move interrupted by a reset ended failed with 0x" << std::hex << error
          << ", not 0xfffa (controller reset during the command)";
    }
  }
  EXPECT_GT(interrupted_failed, 0) << "no move interrupted by a reset ended failed";
  return counts;
}

}  // namespace fieldgate::test
