// Modbus TCP read throughput and latency: fieldgate (with its buses polling) against a bare
// libmodbus server serving a map of the same size, both measured in this run with the same
// clients. Prints both, the throughput ratio and the latency percentiles.
//
//   modbus_bench --fieldgate-port P [--clients 16] [--seconds 5] [--unit 1] [--registers 10]
//                [--rounds 8] [--reference process|thread]
//
// The caller starts fieldgate (see bench/modbus/run). The bare server runs in a process of its
// own, forked before any client thread, as fieldgate runs in its own: a server thread in the
// clients' process switches to and from them without changing address space, which a server
// process (fieldgate's, or any real one) cannot (`--reference thread` keeps it in this process
// for comparison; docs/performance.md, "Session of 2026-12-07, morning").
#include <arpa/inet.h>
#include <fmt/format.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/prctl.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct Result {
  uint64_t requests = 0;
  uint64_t failures = 0;
  std::string first_error;
  std::vector<double> latencies_us;
  double seconds = 0;
};

Result run_clients(int port, int clients, double seconds, int unit, int registers) {
  std::vector<Result> per(static_cast<std::size_t>(clients));
  std::atomic<bool> go{false}, stop{false};
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c)
    threads.emplace_back([&, c] {
      modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
      if (!ctx || modbus_connect(ctx) != 0) {
        per[static_cast<std::size_t>(c)].failures = 1;
        return;
      }
      modbus_set_slave(ctx, unit);
      std::vector<uint16_t> regs(static_cast<std::size_t>(registers));
      auto& r = per[static_cast<std::size_t>(c)];
      r.latencies_us.reserve(200000);
      while (!go) std::this_thread::yield();
      while (!stop) {
        const auto t0 = Clock::now();
        const int rc = modbus_read_input_registers(ctx, 0, registers, regs.data());
        const auto t1 = Clock::now();
        if (rc == registers) {
          ++r.requests;
          r.latencies_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
        } else {
          if (r.failures++ == 0) r.first_error = modbus_strerror(errno);
        }
      }
      modbus_close(ctx);
      modbus_free(ctx);
    });
  const auto start = Clock::now();
  go = true;
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stop = true;
  for (auto& t : threads) t.join();
  Result total;
  total.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  for (auto& r : per) {
    total.requests += r.requests;
    total.failures += r.failures;
    if (total.first_error.empty()) total.first_error = r.first_error;
    total.latencies_us.insert(total.latencies_us.end(), r.latencies_us.begin(),
                              r.latencies_us.end());
  }
  std::sort(total.latencies_us.begin(), total.latencies_us.end());
  return total;
}

double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0;
  return sorted[std::min(sorted.size() - 1,
                         static_cast<std::size_t>(p * static_cast<double>(sorted.size())))];
}

// libmodbus's own multi-client server loop (as in its tests): select() over the listening
// socket and the clients, modbus_receive + modbus_reply on a flat mapping. It serves from a
// child process (serve_in_process) or a thread of this one (serve_in_thread).
class BareServer {
 public:
  explicit BareServer(int registers) {
    ctx_ = modbus_new_tcp("127.0.0.1", 0);
    mapping_ = modbus_mapping_new(0, 0, 0, registers + 1100);
    listen_ = modbus_tcp_listen(ctx_, 32);
    if (listen_ < 0) throw std::runtime_error("the bare server cannot listen");
    sockaddr_in addr{};
    socklen_t len = sizeof addr;
    getsockname(listen_, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
  }
  ~BareServer() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    if (child_ > 0) {
      ::kill(child_, SIGTERM);
      ::waitpid(child_, nullptr, 0);
    }
    ::close(listen_);
    modbus_mapping_free(mapping_);
    modbus_free(ctx_);
  }
  BareServer(const BareServer&) = delete;
  BareServer& operator=(const BareServer&) = delete;
  int port() const { return port_; }

  // Before any other thread exists: the child is a copy of this process at this point.
  void serve_in_process() {
    const pid_t parent = ::getpid();
    child_ = ::fork();
    if (child_ < 0) throw std::runtime_error("fork failed");
    if (child_ == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);
      if (::getppid() != parent) ::_exit(0);
      loop();
      ::_exit(0);
    }
  }
  void serve_in_thread() {
    thread_ = std::thread([this] { loop(); });
  }

 private:
  void loop() {
    fd_set all;
    FD_ZERO(&all);
    FD_SET(listen_, &all);
    int max_fd = listen_;
    uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    while (!stop_) {
      fd_set ready = all;
      timeval tv{0, 100000};
      if (select(max_fd + 1, &ready, nullptr, nullptr, &tv) <= 0) continue;
      for (int fd = 0; fd <= max_fd; ++fd) {
        if (!FD_ISSET(fd, &ready)) continue;
        if (fd == listen_) {
          const int client = accept(listen_, nullptr, nullptr);
          if (client >= 0) {
            FD_SET(client, &all);
            max_fd = std::max(max_fd, client);
          }
          continue;
        }
        modbus_set_socket(ctx_, fd);
        const int rc = modbus_receive(ctx_, query);
        if (rc > 0) {
          modbus_reply(ctx_, query, rc, mapping_);
        } else if (rc == -1) {
          ::close(fd);
          FD_CLR(fd, &all);
        }
      }
    }
  }

  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  int listen_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  pid_t child_ = -1;
};

void print(const char* name, const Result& r) {
  fmt::print(
      "{:<10} {:>10.0f} req/s  p50 {:>7.1f} us  p99 {:>7.1f} us  max {:>8.1f} us  ({} requests, {} "
      "failures)\n",
      name, static_cast<double>(r.requests) / r.seconds, percentile(r.latencies_us, 0.50),
      percentile(r.latencies_us, 0.99), r.latencies_us.empty() ? 0 : r.latencies_us.back(),
      r.requests, r.failures);
  if (r.failures > 0) fmt::print("           first failure: {}\n", r.first_error);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Modbus TCP read benchmark: fieldgate against a bare libmodbus server"};
  int fieldgate_port = 0, clients = 16, unit = 1, registers = 10;
  double seconds = 5;
  int rounds = 8;
  std::string reference = "process";
  app.add_option("--fieldgate-port", fieldgate_port, "port fieldgate listens on")->required();
  app.add_option("--clients", clients, "concurrent clients");
  app.add_option("--seconds", seconds, "time each server is measured, over all rounds");
  app.add_option("--rounds", rounds, "slices each server's time is measured in, alternating")
      ->check(CLI::Range(2, 100));
  app.add_option("--reference", reference,
                 "where the bare libmodbus server runs: its own process, or a thread of this one")
      ->check(CLI::IsMember({"process", "thread"}));
  app.add_option("--unit", unit, "unit ID to read on fieldgate");
  app.add_option("--registers", registers, "input registers per read (from address 0)");
  CLI11_PARSE(app, argc, argv);

  BareServer bare(registers);
  if (reference == "process")
    bare.serve_in_process();
  else
    bare.serve_in_thread();
  // Alternate in short slices, in the order ABBA within each pair of rounds, so drift in
  // machine load (a busy core, another benchmark's leftovers) falls on both servers alike.
  auto merge = [](Result a, const Result& b) {
    a.requests += b.requests;
    a.failures += b.failures;
    if (a.first_error.empty()) a.first_error = b.first_error;
    a.seconds += b.seconds;
    a.latencies_us.insert(a.latencies_us.end(), b.latencies_us.begin(), b.latencies_us.end());
    return a;
  };
  Result b, g;
  const double slice = seconds / rounds;
  for (int round = 0; round < rounds; ++round) {
    if (round % 2 == 0) {
      b = merge(std::move(b), run_clients(bare.port(), clients, slice, 1, registers));
      g = merge(std::move(g), run_clients(fieldgate_port, clients, slice, unit, registers));
    } else {
      g = merge(std::move(g), run_clients(fieldgate_port, clients, slice, unit, registers));
      b = merge(std::move(b), run_clients(bare.port(), clients, slice, 1, registers));
    }
  }
  std::sort(b.latencies_us.begin(), b.latencies_us.end());
  std::sort(g.latencies_us.begin(), g.latencies_us.end());
  fmt::print(
      "{} clients, {} registers per read, {:.1f} s each in {} alternating slices; libmodbus in "
      "{}\n",
      clients, registers, seconds, rounds,
      reference == "process" ? "a process of its own" : "a thread of the clients' process");
  print("libmodbus", b);
  print("fieldgate", g);
  const double ratio = (static_cast<double>(g.requests) / g.seconds) /
                       std::max(1.0, static_cast<double>(b.requests) / b.seconds);
  fmt::print("throughput ratio fieldgate/libmodbus: {:.2f}\n", ratio);
  return (g.requests == 0 || b.requests == 0) ? 1 : 0;
}
