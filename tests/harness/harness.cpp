#include "harness.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <random>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace fieldgate::test {

namespace fs = std::filesystem;

ScratchDir::ScratchDir() {
  std::random_device rd;
  path_ = fs::temp_directory_path() /
          ("fieldgate-it-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
  fs::create_directories(path_);
}

ScratchDir::~ScratchDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

ChildProcess::ChildProcess(std::vector<std::string> argv, fs::path log_file,
                           std::vector<std::string> env)
    : log_file_(std::move(log_file)) {
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
  const int log_fd = ::open(log_file_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (log_fd < 0) throw std::runtime_error("cannot create " + log_file_.string());
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[0], 0);
  posix_spawn_file_actions_adddup2(&actions, log_fd, 1);
  posix_spawn_file_actions_adddup2(&actions, log_fd, 2);
  std::vector<char*> args;
  for (auto& a : argv) args.push_back(a.data());
  args.push_back(nullptr);
  std::vector<std::string> env_strings;
  for (char** e = environ; *e; ++e) env_strings.emplace_back(*e);
  for (auto& e : env) env_strings.push_back(e);
  std::vector<char*> envp;
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  const int rc = ::posix_spawn(&pid_, args[0], &actions, nullptr, args.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  ::close(pipe_fds[0]);
  ::close(log_fd);
  if (rc != 0) {
    ::close(pipe_fds[1]);
    throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));
  }
  stdin_fd_ = pipe_fds[1];
}

ChildProcess::~ChildProcess() {
  terminate();
  if (stdin_fd_ >= 0) ::close(stdin_fd_);
}

void ChildProcess::send_line(const std::string& line) {
  const std::string text = line + "\n";
  if (::write(stdin_fd_, text.data(), text.size()) != static_cast<ssize_t>(text.size()))
    throw std::runtime_error("cannot write to child stdin");
}

std::string ChildProcess::log() const {
  std::ifstream in(log_file_);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool ChildProcess::running() {
  if (status_) return false;
  int status = 0;
  if (::waitpid(pid_, &status, WNOHANG) == pid_) {
    status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    return false;
  }
  return true;
}

int ChildProcess::wait_exit() {
  if (!status_) {
    int status = 0;
    ::waitpid(pid_, &status, 0);
    status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  return *status_;
}

void ChildProcess::signal(int signal_number) {
  if (pid_ > 0 && running()) ::kill(pid_, signal_number);
}

void ChildProcess::terminate() {
  if (pid_ <= 0 || !running()) return;
  ::kill(pid_, SIGTERM);
  for (int i = 0; i < 300 && running(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if (running()) ::kill(pid_, SIGKILL);
  wait_exit();
}

bool wait_until(const std::function<bool()>& pred, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return pred();
}

std::optional<std::string> control_answer(ChildProcess& sim, const std::string& line,
                                          const std::string& tag,
                                          std::chrono::milliseconds timeout) {
  const auto answers = [&] {
    const std::string log = sim.log();
    std::size_t n = 0;
    for (auto at = log.find(tag); at != std::string::npos; at = log.find(tag, at + 1)) ++n;
    return n;
  };
  const std::size_t before = answers();
  sim.send_line(line);
  if (!wait_until([&] { return answers() > before; }, timeout)) return std::nullopt;
  const std::string log = sim.log();
  return log.substr(log.rfind(tag));
}

ModbusClient::ModbusClient(const std::string& host, int port) {
  ctx_ = modbus_new_tcp(host.c_str(), port);
  if (!ctx_ || modbus_connect(ctx_) != 0)
    throw std::runtime_error("cannot connect to Modbus server on port " + std::to_string(port));
  modbus_set_response_timeout(ctx_, 5, 0);
}

ModbusClient::~ModbusClient() {
  if (ctx_) {
    modbus_close(ctx_);
    modbus_free(ctx_);
  }
}

ModbusResult ModbusClient::finish(int rc, std::vector<uint16_t> values) {
  ModbusResult r;
  if (rc >= 0) {
    r.values = std::move(values);
    return r;
  }
  const int e = errno;
  r.exception = (e > MODBUS_ENOBASE && e < MODBUS_ENOBASE + 0x20) ? e - MODBUS_ENOBASE : -1;
  return r;
}

ModbusResult ModbusClient::read_input(int unit, int address, int count) {
  std::vector<uint16_t> v(static_cast<std::size_t>(count));
  modbus_set_slave(ctx_, unit);
  const int rc = modbus_read_input_registers(ctx_, address, count, v.data());
  return finish(rc, std::move(v));
}

ModbusResult ModbusClient::read_holding(int unit, int address, int count) {
  std::vector<uint16_t> v(static_cast<std::size_t>(count));
  modbus_set_slave(ctx_, unit);
  const int rc = modbus_read_registers(ctx_, address, count, v.data());
  return finish(rc, std::move(v));
}

ModbusResult ModbusClient::read_discrete(int unit, int address, int count) {
  std::vector<uint8_t> bits(static_cast<std::size_t>(count));
  modbus_set_slave(ctx_, unit);
  const int rc = modbus_read_input_bits(ctx_, address, count, bits.data());
  return finish(rc, std::vector<uint16_t>(bits.begin(), bits.end()));
}

ModbusResult ModbusClient::write(int unit, int address, const std::vector<uint16_t>& values) {
  modbus_set_slave(ctx_, unit);
  return finish(
      modbus_write_registers(ctx_, address, static_cast<int>(values.size()), values.data()), {});
}

ModbusResult ModbusClient::write_single(int unit, int address, uint16_t value) {
  modbus_set_slave(ctx_, unit);
  return finish(modbus_write_register(ctx_, address, value), {});
}

ModbusResult ModbusClient::write_coil(int unit, int address, bool value) {
  modbus_set_slave(ctx_, unit);
  return finish(modbus_write_bit(ctx_, address, value ? 1 : 0), {});
}

std::optional<int32_t> ModbusClient::read_input_i32(int unit, int address) {
  auto r = read_input(unit, address, 2);
  if (!r.ok()) return std::nullopt;
  return static_cast<int32_t>((static_cast<uint32_t>(r.values[0]) << 16) | r.values[1]);
}

ModbusResult ModbusClient::write_i32(int unit, int address, int32_t value) {
  const auto bits = static_cast<uint32_t>(value);
  return write(unit, address, {static_cast<uint16_t>(bits >> 16), static_cast<uint16_t>(bits)});
}

Plant::Plant(std::vector<SimulatedBus> buses, std::string modbus_extra,
             std::vector<std::string> daemon_env) {
  std::ostringstream config;
  config << "modbus:\n  listen: 127.0.0.1:0\n"
         << modbus_extra << "models: " FIELDGATE_SOURCE_DIR "/config/models\n"
         << "buses:\n";
  for (std::size_t i = 0; i < buses.size(); ++i) {
    auto& bus = buses[i];
    const auto link = dir_ / ("link" + std::to_string(i));
    for (auto& arg : bus.sim_argv) {
      if (arg == "{link}") arg = link.string();
      if (arg.rfind("{dir}", 0) == 0) arg = dir_.path().string() + arg.substr(5);
    }
    sims_.push_back(
        std::make_unique<ChildProcess>(bus.sim_argv, dir_ / ("sim" + std::to_string(i) + ".log")));
    if (!wait_until([&] { return fs::exists(link); }, std::chrono::seconds(5)))
      throw std::runtime_error("simulator did not create its link: " + sims_.back()->log());
    config << "  - name: " << bus.name << "\n    protocol: " << bus.protocol << "\n"
           << "    serial: {device: " << link.string() << ", " << bus.serial << "}\n"
           << "    timing: {" << bus.timing
           << "}\n"
           // FIELDGATE_PLANT_TRACE: every frame in the daemon's log (docs/wire-trace.md).
           << (std::getenv("FIELDGATE_PLANT_TRACE") ? "    trace: true\n" : "") << "    nodes:\n"
           << bus.nodes;
  }
  std::ofstream(config_path()) << config.str();
  daemon_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{FIELDGATE_BINARY, "--config", config_path().string()},
      dir_ / "daemon.log", std::move(daemon_env));
  const std::regex listening("modbus: listening on [0-9.]+:([0-9]+)");
  std::smatch m;
  const bool up = wait_until([&] {
    const std::string log = daemon_->log();
    return std::regex_search(log, m, listening) || !daemon_->running();
  });
  const std::string log = daemon_->log();
  if (!up || !std::regex_search(log, m, listening))
    throw std::runtime_error("daemon did not start listening:\n" + log);
  port_ = std::stoi(m[1]);
}

std::vector<JournalEntry> read_journal(const std::filesystem::path& file) {
  std::vector<JournalEntry> entries;
  std::ifstream in(file);
  std::string line;
  static const std::regex format(R"(^(\d+) (.*) -> (.*?)(?: (late|dropped|garbled|truncated))?$)");
  while (std::getline(in, line)) {
    std::smatch m;
    if (!std::regex_match(line, m, format)) continue;
    entries.push_back({std::stoll(m[1]), m[2], m[3], m[4]});
  }
  return entries;
}

Plant::~Plant() {
  daemon_->terminate();
  for (auto& sim : sims_) sim->terminate();
}

CopleyPlant::CopleyPlant(const std::string& sim_nodes, const std::string& config_nodes)
    : Plant({SimulatedBus{"copley",
                          "copley-ascii",
                          {FIELDGATE_SIM_COPLEY, "--link", "{link}", "--nodes", sim_nodes},
                          "baud: 115200",
                          "reply_timeout: 50ms, byte_timeout: 10ms, retries: 1, "
                          "offline_after: 3, probe_interval: 300ms",
                          config_nodes}}) {}

int listener_port(ChildProcess& daemon, const std::string& name) {
  const std::regex listening("modbus " + name + ": listening on [0-9.]+:([0-9]+)");
  std::smatch m;
  std::string log;
  if (!wait_until([&] {
        log = daemon.log();
        return std::regex_search(log, m, listening);
      }))
    return -1;
  return std::stoi(m[1]);
}

std::string http_get(int port, const std::string& target) {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(s);
    return {};
  }
  const std::string req = "GET " + target + " HTTP/1.1\r\nHost: localhost\r\n\r\n";
  ::send(s, req.data(), req.size(), 0);
  std::string response;
  char buf[4096];
  ssize_t n;
  while ((n = ::recv(s, buf, sizeof buf, 0)) > 0) response.append(buf, static_cast<std::size_t>(n));
  ::close(s);
  return response;
}

}  // namespace fieldgate::test
