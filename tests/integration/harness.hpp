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
  int wait_exit();   // exit code, or 128+signal

 private:
  pid_t pid_ = -1;
  int stdin_fd_ = -1;
  std::filesystem::path log_file_;
  std::optional<int> status_;
};

// Polls pred every 10 ms until it holds or the timeout passes.
bool wait_until(const std::function<bool()>& pred,
                std::chrono::milliseconds timeout = std::chrono::seconds(10));

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

// The Copley simulator plus the daemon configured for it.
class CopleyPlant {
 public:
  // nodes: simulated node IDs; config_nodes: the YAML of the bus's `nodes:` list.
  CopleyPlant(const std::string& sim_nodes, const std::string& config_nodes,
              const std::string& timing = "");
  ~CopleyPlant();
  int port() const { return port_; }
  ChildProcess& sim() { return *sim_; }
  ChildProcess& daemon() { return *daemon_; }
  const ScratchDir& dir() const { return dir_; }

 private:
  ScratchDir dir_;
  std::unique_ptr<ChildProcess> sim_;
  std::unique_ptr<ChildProcess> daemon_;
  int port_ = 0;
};

}  // namespace fieldgate::test
