// Command latency: a Modbus write to a Copley amplifier's position_command (holding 4-5) until
// the first byte of its "s r0xca VALUE" command is on the wire, as the simulator's wire log
// (--wire-log) timestamps it on CLOCK_MONOTONIC, the clock std::chrono::steady_clock reads here.
// Also reports the bus's transaction cycle (start to start of consecutive requests) seen in the
// same log, the "one in-flight transaction" of the busy-bus bar.
//
//   latency_bench --port P --wire-log FILE [--unit 1] [--samples 200] [--label idle]
//                 [--samples-file F]  (one line per write: its start and its first byte, in ns)
#include <fmt/format.h>
#include <modbus/modbus.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct WireLine {
  long long started_ns = 0;
  std::string request;
};

// Lines appended to the wire log since the last call.
class WireLog {
 public:
  explicit WireLog(const std::string& path) : in_(path) {}
  std::vector<WireLine> fresh() {
    std::vector<WireLine> out;
    std::string line;
    in_.clear();
    while (std::getline(in_, line)) {
      if (in_.eof()) {  // a partial line: read it again next time
        in_.clear();
        in_.seekg(-static_cast<std::streamoff>(line.size()), std::ios::cur);
        break;
      }
      std::istringstream fields(line);
      WireLine w;
      long long arrived = 0, delay = 0;
      std::size_t request = 0, echoed = 0, reply = 0;
      fields >> w.started_ns >> arrived >> request >> echoed >> reply >> delay;
      std::getline(fields >> std::ws, w.request);
      out.push_back(std::move(w));
    }
    return out;
  }

 private:
  std::ifstream in_;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Modbus write to first command byte on the wire"};
  int port = 0, unit = 1, samples = 200;
  std::string wire_log_path, label = "bus", samples_path;
  app.add_option("--port", port, "fieldgate's Modbus port")->required();
  app.add_option("--wire-log", wire_log_path, "the simulator's --wire-log file")->required();
  app.add_option("--unit", unit, "unit ID of a Copley amplifier");
  app.add_option("--samples", samples, "writes to time");
  app.add_option("--label", label, "name printed with the figures");
  app.add_option("--samples-file", samples_path,
                 "where to write each write's start and first byte");
  CLI11_PARSE(app, argc, argv);

  modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
  if (!ctx || modbus_connect(ctx) != 0) {
    fmt::print(stderr, "cannot connect to 127.0.0.1:{}\n", port);
    return 1;
  }
  modbus_set_slave(ctx, unit);
  modbus_set_response_timeout(ctx, 2, 0);
  std::ofstream samples_file;
  if (!samples_path.empty()) samples_file.open(samples_path);
  WireLog log(wire_log_path);
  log.fresh();
  std::vector<double> latency_us, cycle_us;
  int missing = 0, failed = 0;
  long long previous_start = 0;
  for (int i = 0; i < samples; ++i) {
    const int value = 100000 + i;
    const uint16_t words[2] = {static_cast<uint16_t>(value >> 16), static_cast<uint16_t>(value)};
    const std::string command = fmt::format("r0xca {}\\r", value);
    const auto t0 = Clock::now();
    const int rc = modbus_write_registers(ctx, 4, 2, words);
    if (rc != 2) ++failed;
    bool found = false;
    // The write is confirmed, so its command has been logged (or it never went out).
    for (int tries = 0; tries < 50 && !found; ++tries) {
      for (const auto& w : log.fresh()) {
        if (previous_start > 0 && w.started_ns > previous_start)
          cycle_us.push_back(static_cast<double>(w.started_ns - previous_start) / 1000.0);
        previous_start = w.started_ns;
        if (w.request.size() >= command.size() &&
            w.request.compare(w.request.size() - command.size(), command.size(), command) == 0) {
          const long long t0_ns =
              std::chrono::duration_cast<std::chrono::nanoseconds>(t0.time_since_epoch()).count();
          latency_us.push_back(static_cast<double>(w.started_ns - t0_ns) / 1000.0);
          if (samples_file.is_open()) samples_file << t0_ns << ' ' << w.started_ns << '\n';
          found = true;
        }
      }
      if (!found) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    if (!found) ++missing;
    // Writes land at varied points of the poll cycle.
    std::this_thread::sleep_for(std::chrono::microseconds(3000 + (i * 7919) % 9000));
  }
  modbus_close(ctx);
  modbus_free(ctx);
  const double cycle_p99 = percentile(cycle_us, 0.99);
  fmt::print(
      "{:<6} {} samples: write->first byte p50 {:.0f} us  p99 {:.0f} us  max {:.0f} us; "
      "transaction cycle p50 {:.0f} us p99 {:.0f} us; bound (one cycle + 1 ms) {:.0f} us; "
      "p99/bound {:.2f}; {} failed, {} not seen\n",
      label, latency_us.size(), percentile(latency_us, 0.5), percentile(latency_us, 0.99),
      latency_us.empty() ? 0 : *std::max_element(latency_us.begin(), latency_us.end()),
      percentile(cycle_us, 0.5), cycle_p99, cycle_p99 + 1000,
      percentile(latency_us, 0.99) / (cycle_p99 + 1000), failed, missing);
  return latency_us.empty() ? 1 : 0;
}
