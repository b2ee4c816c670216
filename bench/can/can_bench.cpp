// CAN benchmark: SDO polling throughput of the CAN bus runtime across N simulated nodes
// (fieldgate-sim-canopen), as a ratio to the bare request/response rate of the same interface
// (can_pingpong) measured in the same run. Run it where vcan0 exists: bench/can/run.
#include <fmt/format.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "gateway/bus/can_bus.hpp"
#include "gateway/config/config_loader.hpp"
#include "gateway/lifecycle/log.hpp"

extern char** environ;

namespace fs = std::filesystem;
using namespace fieldgate;
using Clock = std::chrono::steady_clock;

namespace {

std::optional<double> pingpong_rate(const std::string& program, const std::string& ifname,
                                    double seconds) {
  const std::string command = fmt::format("'{}' '{}' {}", program, ifname, seconds);
  FILE* out = ::popen(command.c_str(), "r");
  if (!out) return std::nullopt;
  char line[256];
  std::optional<double> rate;
  while (std::fgets(line, sizeof line, out)) {
    double r = 0;
    if (std::sscanf(line, "pingpong_round_trips_per_s %lf", &r) == 1) rate = r;
  }
  if (::pclose(out) != 0) return std::nullopt;
  return rate;
}

rusage usage_now() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return u;
}

double process_cpu_seconds() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e6;
}

class Simulator {
 public:
  Simulator(const std::string& program, const std::string& ifname, int nodes, const fs::path& log)
      : log_(log) {
    std::vector<std::string> args{
        program, "--interface", ifname, "--nodes", fmt::format("1-{}", nodes), "--heartbeat", "0"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (::posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  // CPU seconds the simulator has used so far (user + system).
  double cpu_seconds() const {
    std::ifstream in(fmt::format("/proc/{}/stat", pid_));
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto close = text.rfind(')');
    if (close == std::string::npos) return 0;
    std::istringstream fields(text.substr(close + 2));
    std::string f;
    double ticks = 0;
    for (int i = 3; fields >> f && i <= 15; ++i)
      if (i == 14 || i == 15) ticks += std::stod(f);
    return ticks / static_cast<double>(::sysconf(_SC_CLK_TCK));
  }
  ~Simulator() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  bool wait_ready() const {
    for (int i = 0; i < 200 && pid_ > 0; ++i) {
      std::ifstream in(log_);
      std::stringstream s;
      s << in.rdbuf();
      if (s.str().find("ready ") != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }

 private:
  fs::path log_;
  pid_t pid_ = -1;
};

struct PollRun {
  double rate = 0;
  uint64_t polls = 0, timeouts = 0, errors = 0;
  double mean_ms = 0;
  double own_cpu = 0, sim_cpu = 0;  // CPU seconds per second
  rusage before{}, after{};
};

// A fresh CAN bus polling every node for `seconds`, run as the daemon runs it.
PollRun poll_run(std::shared_ptr<const LoadedConfig> config, const Simulator& sim, double seconds) {
  asio::io_context io{1};  // one thread, as the daemon runs it
  auto bus =
      std::make_shared<CanBus>(io.get_executor(), config, config->gateway.buses[0], 0, nullptr);
  asio::co_spawn(
      io, [bus]() -> asio::awaitable<void> { co_await bus->run(); }, asio::detached);
  PollRun run;
  BusCounters before, after;
  Clock::time_point start, end;
  asio::co_spawn(
      io,
      [&]() -> asio::awaitable<void> {
        asio::steady_timer t(io);
        // Warm up: the interface open and every node online (answering its polls).
        const auto give_up = Clock::now() + std::chrono::seconds(10);
        for (;;) {
          t.expires_after(std::chrono::milliseconds(50));
          co_await t.async_wait(asio::use_awaitable);
          const auto images = bus->node_images();
          const bool all_online = std::all_of(images.begin(), images.end(), [](const auto& n) {
            return n->state == NodeState::online;
          });
          if (all_online || Clock::now() > give_up) break;
        }
        before = bus->counters();
        run.sim_cpu = sim.cpu_seconds();
        run.own_cpu = process_cpu_seconds();
        run.before = usage_now();
        start = Clock::now();
        t.expires_after(
            std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds)));
        co_await t.async_wait(asio::use_awaitable);
        after = bus->counters();
        end = Clock::now();
        run.sim_cpu = sim.cpu_seconds() - run.sim_cpu;
        run.own_cpu = process_cpu_seconds() - run.own_cpu;
        run.after = usage_now();
        bus->stop();
      },
      asio::detached);
  io.run();
  const double elapsed = std::chrono::duration<double>(end - start).count();
  run.polls = after.transactions - before.transactions;
  run.timeouts = after.timeouts - before.timeouts;
  run.errors = after.errors - before.errors;
  run.rate = static_cast<double>(run.polls) / elapsed;
  run.mean_ms = run.polls > 0 ? (after.latency_sum - before.latency_sum) /
                                    static_cast<double>(run.polls) * 1000
                              : 0.0;
  run.own_cpu /= elapsed;
  run.sim_cpu /= elapsed;
  return run;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : (v[v.size() / 2 - 1] + v[v.size() / 2]) / 2;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"SDO polling across simulated CANopen nodes vs a bare CAN ping-pong"};
  std::string ifname = "vcan0";
  int nodes = 32;
  double seconds = 10;
  int rounds = 5;
  std::string sim_program, pingpong_program;
  app.add_option("--interface", ifname)->capture_default_str();
  app.add_option("--nodes", nodes, "simulated nodes (1..127)")
      ->capture_default_str()
      ->check(CLI::Range(1, 127));
  app.add_option("--seconds", seconds, "measuring time of each part, over all rounds")
      ->capture_default_str();
  app.add_option("--rounds", rounds,
                 "ping-pong and SDO polling alternate this many times; the ratio is the median "
                 "of the rounds' ratios, so a change in the machine's load hits both alike")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  app.add_option("--sim", sim_program, "fieldgate-sim-canopen")->required();
  app.add_option("--pingpong", pingpong_program, "can_pingpong")->required();
  CLI11_PARSE(app, argc, argv);
  log::set_verbosity(log::Level::warning);

  const fs::path dir =
      fs::temp_directory_path() / fmt::format("fieldgate-can-bench-{}", ::getpid());
  fs::create_directories(dir / "models");
  // One SDO-polled object per node, due every 10 us: always overdue, so each node's worker
  // polls back to back and the rate is what the bus achieves with every node busy.
  std::ofstream(dir / "models" / "bench.yaml")
      << "model: can-bench\nfamily: canopen\npoll_classes: {fast: 10us}\n"
      << "points:\n  position_actual:\n    type: int32\n"
      << "    read: {object: \"0x6064:0\", data_type: INTEGER32}\n    poll: fast\n";
  {
    std::ofstream gw(dir / "gw.yaml");
    gw << "models: " << (dir / "models").string() << "\nbuses:\n  - name: can\n"
       << "    protocol: canopen\n    can: {interface: " << ifname << "}\n"
       << "    timing: {reply_timeout: 500ms, retries: 0, offline_after: 10}\n    nodes:\n";
    for (int n = 1; n <= nodes; ++n)
      gw << fmt::format("      - {{name: n{0}, address: {0}, model: can-bench, unit_id: {0}}}\n",
                        n);
  }
  Diagnostics d;
  auto loaded = load_gateway_config((dir / "gw.yaml").string(), d);
  if (!loaded) {
    fmt::print(stderr, "can_bench: {}", d.to_text());
    return 1;
  }
  std::shared_ptr<const LoadedConfig> config = std::make_shared<LoadedConfig>(std::move(*loaded));

  int rc = 0;
  {
    Simulator sim(sim_program, ifname, nodes, dir / "sim.log");
    if (!sim.wait_ready()) {
      fmt::print(stderr, "can_bench: the simulator did not start\n");
      fs::remove_all(dir);
      return 1;
    }
    const double part = seconds / rounds;
    std::vector<double> pings, polls, ratios;
    for (int r = 1; r <= rounds && rc == 0; ++r) {
      const auto ping = pingpong_rate(pingpong_program, ifname, part);
      if (!ping || *ping <= 0) {
        fmt::print(stderr, "can_bench: the ping-pong did not run\n");
        rc = 1;
        break;
      }
      const auto run = poll_run(config, sim, part);
      fmt::print(
          "round {}: pingpong {:.1f}/s, sdo polls {:.1f}/s ({} timeouts, {} errors, mean "
          "transfer {:.2f} ms, cpu fieldgate {:.2f} simulator {:.2f}, context switches {}+{}), "
          "ratio {:.2f}\n",
          r, *ping, run.rate, run.timeouts, run.errors, run.mean_ms, run.own_cpu, run.sim_cpu,
          run.after.ru_nvcsw - run.before.ru_nvcsw, run.after.ru_nivcsw - run.before.ru_nivcsw,
          run.rate / *ping);
      pings.push_back(*ping);
      polls.push_back(run.rate);
      ratios.push_back(run.rate / *ping);
    }
    if (rc == 0 && median(polls) <= 0) {
      fmt::print(stderr, "can_bench: no SDO transfer completed\n");
      rc = 1;
    }
    if (rc == 0) {
      fmt::print("pingpong_round_trips_per_s {:.1f}\n", median(pings));
      fmt::print("sdo_polls_per_s {:.1f}  ({} nodes)\n", median(polls), nodes);
      // Under an emulated CPU (QEMU TCG) only this ratio means anything: both rates ran there.
      const char* backend = std::getenv("FIELDGATE_VCAN_BACKEND");
      fmt::print("ratio {:.2f}  (median of {} rounds; bar: at least 0.50; vcan: {})\n",
                 median(ratios), rounds, backend ? backend : "unknown");
    }
  }
  fs::remove_all(dir);
  return rc;
}
