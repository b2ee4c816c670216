#pragma once

// Runs the real fieldgate daemon and simulators as child processes, and talks Modbus TCP to
// the daemon with libmodbus, for end-to-end tests.

#include <modbus/modbus.h>
#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace fieldgate::test {

// A scratch directory removed at the end of the test.
class ScratchDir {
 public:
  ScratchDir();
  ~ScratchDir();
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// A child process with a pipe to its stdin and its stderr in a file.
class ChildProcess {
 public:
  ChildProcess(std::vector<std::string> argv, std::filesystem::path log_file,
               std::vector<std::string> env = {});
  ~ChildProcess();
  void send_line(const std::string& line);
  std::string log() const;
  bool running();
  void terminate();  // SIGTERM and wait
  void signal(int signal_number);
  int wait_exit();  // exit code, or 128+signal

 private:
  pid_t pid_ = -1;
  int stdin_fd_ = -1;
  std::filesystem::path log_file_;
  std::optional<int> status_;
};

// Polls pred every 10 ms until it holds or the timeout passes.
bool wait_until(const std::function<bool()>& pred,
                std::chrono::milliseconds timeout = std::chrono::seconds(10));

// Sends a control line to a simulator and waits for its answer, a log line holding `tag` (one
// more than before); returns the log from the last `tag` on, or nullopt if none came in time.
std::optional<std::string> control_answer(
    ChildProcess& sim, const std::string& line, const std::string& tag,
    std::chrono::milliseconds timeout = std::chrono::seconds(5));

struct ModbusResult {
  std::vector<uint16_t> values;
  int exception = 0;  // Modbus exception code, 0 on success, -1 on another error
  bool ok() const { return exception == 0; }
};

class ModbusClient {
 public:
  ModbusClient(const std::string& host, int port);
  ~ModbusClient();
  ModbusResult read_input(int unit, int address, int count);
  ModbusResult read_holding(int unit, int address, int count);
  ModbusResult read_discrete(int unit, int address, int count);
  ModbusResult write(int unit, int address, const std::vector<uint16_t>& values);
  ModbusResult write_single(int unit, int address, uint16_t value);
  ModbusResult write_coil(int unit, int address, bool value);
  // 32-bit values, high word first (the daemon's default order).
  std::optional<int32_t> read_input_i32(int unit, int address);
  ModbusResult write_i32(int unit, int address, int32_t value);

 private:
  ModbusResult finish(int rc, std::vector<uint16_t> values);
  modbus_t* ctx_ = nullptr;
};

// One simulated serial bus: a simulator behind a PTY and the bus section of the daemon's config.
struct SimulatedBus {
  std::string name;
  std::string protocol;
  // Simulator command line; the argument "{link}" is replaced by the PTY link path, "{dir}" at
  // the start of an argument by the plant's scratch directory (e.g. "{dir}/journal").
  std::vector<std::string> sim_argv;
  std::string serial = "baud: 115200";  // YAML flow-map content besides the device
  std::string timing =
      "reply_timeout: 50ms, byte_timeout: 10ms, retries: 1, offline_after: 3, "
      "probe_interval: 300ms";
  std::string nodes;  // YAML list items of the bus's nodes, indented by six spaces
};

// Simulators plus the real daemon configured for them, listening on a free loopback port.
class Plant {
 public:
  explicit Plant(std::vector<SimulatedBus> buses, std::string modbus_extra = "",
                 std::vector<std::string> daemon_env = {});
  ~Plant();
  int port() const { return port_; }
  ChildProcess& sim(std::size_t i = 0) { return *sims_.at(i); }
  std::size_t sim_count() const { return sims_.size(); }
  ChildProcess& daemon() { return *daemon_; }
  const ScratchDir& dir() const { return dir_; }
  std::filesystem::path config_path() const { return dir_ / "gateway.yaml"; }

 private:
  ScratchDir dir_;
  std::vector<std::unique_ptr<ChildProcess>> sims_;
  std::unique_ptr<ChildProcess> daemon_;
  int port_ = 0;
};

// The Copley simulator with the given node IDs, and the daemon's nodes for it.
class CopleyPlant : public Plant {
 public:
  CopleyPlant(const std::string& sim_nodes, const std::string& config_nodes);
};

// One line of a simulator's device journal (--journal, sim/common LineExchange): a request the
// device executed and the reply it produced, escaped as the simulator logs them ("ok\\r"), and
// the fault injected on the way out ("late", "dropped", "garbled", "truncated" or "").
struct JournalEntry {
  long long at_us = 0;
  std::string request;
  std::string reply;
  std::string fault;
};
std::vector<JournalEntry> read_journal(const std::filesystem::path& file);

// The TCP port the daemon logs for Modbus listener `name`, once logged (-1 after 10 s).
int listener_port(ChildProcess& daemon, const std::string& name);

// The raw response (status line, headers, body) to an HTTP/1.1 GET on the loopback port; "" if
// the connection is refused.
std::string http_get(int port, const std::string& target);

}  // namespace fieldgate::test
