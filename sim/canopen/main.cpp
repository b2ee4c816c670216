// fieldgate-sim-canopen: CiA 301/402 drives on a SocketCAN interface, controlled by line
// commands on stdin.
#include "network.hpp"
#include "socketcan.hpp"

#include <fmt/format.h>
#include <poll.h>
#include <signal.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <map>
#include <string>
#include <system_error>

namespace canopen = fieldgate::sim::canopen;
using canopen::Clock;

namespace {

volatile sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

std::string wall_time() {
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const auto us = std::chrono::duration_cast<std::chrono::microseconds>(now).count();
  return fmt::format("{}.{:06}", us / 1000000, us % 1000000);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"CANopen CiA 301/402 drive simulator on SocketCAN"};
  std::string interface = "vcan0";
  std::string nodes_text = "1";
  bool verbose = false;
  canopen::NodeConfig config;
  config.heartbeat_ms = 0;  // as a CiA 301 device ships: heartbeat off until a master sets 0x1017
  app.add_option("-i,--interface", interface, "SocketCAN interface")->capture_default_str();
  app.add_option("-n,--nodes", nodes_text, "node IDs, e.g. 2,3 or 1-32")->capture_default_str();
  app.add_option("--heartbeat", config.heartbeat_ms,
                 "producer heartbeat time 0x1017 at power-up (ms); 0, the CiA 301 default, sends "
                 "none until a master sets it")
      ->capture_default_str();
  const std::map<std::string, canopen::HeartbeatObject> heartbeat_objects{
      {"normal", canopen::HeartbeatObject::normal},
      {"absent", canopen::HeartbeatObject::absent},
      {"silent", canopen::HeartbeatObject::silent}};
  app.add_option("--heartbeat-object", config.heartbeat_object,
                 "normal: 0x1017 read/write; absent: no 0x1017 (node guarding only); silent: "
                 "0x1017 takes writes but no heartbeat is sent")
      ->transform(CLI::CheckedTransformer(heartbeat_objects, CLI::ignore_case))
      ->default_str("normal");
  bool no_guarding = false;
  app.add_flag("--no-node-guarding", no_guarding,
               "ignore node guarding requests (RTR on 0x700+id)");
  bool no_device_name = false;
  app.add_flag("--no-device-name", no_device_name,
               "no manufacturer device name 0x1008 (optional in CiA 301; uploads are aborted "
               "with 0x06020000)");
  app.add_option("--power-up-error", config.power_up_error,
                 "error code the nodes power up with (error register set, drive in Fault, EMCY "
                 "after boot-up), e.g. 0x5000; cleared by a CiA 402 fault reset")
      ->check(CLI::Range(0, 0xFFFF));
  app.add_flag("--start-needs-no-error", config.start_needs_no_error,
               "refuse NMT start while the error register is set (the node stays "
               "pre-operational)");
  app.add_option("--tpdo-event", config.tpdo_event_ms, "default TPDO1 event timer (ms)")
      ->capture_default_str();
  unsigned sdo_timeout_ms = 1000;
  app.add_option("--sdo-timeout", sdo_timeout_ms,
                 "abort a segmented transfer after this long without a segment (ms); raise it "
                 "to drive transfers by hand with cansend")
      ->capture_default_str();
  app.add_flag("-v,--verbose", verbose, "log frames (candump -L format) and state changes");
  app.footer(
      "stdin commands: power-off ID | power-on ID | fault ID CODE | status [ID] | help | quit");
  CLI11_PARSE(app, argc, argv);
  config.sdo_timeout = std::chrono::milliseconds(sdo_timeout_ms);
  config.node_guarding = !no_guarding;
  config.device_name_object = !no_device_name;

  std::vector<std::uint8_t> ids;
  try {
    ids = canopen::parse_node_ids(nodes_text);
  } catch (const std::invalid_argument& e) {
    fmt::print(stderr, "fieldgate-sim-canopen: --nodes: {}\n", e.what());
    return 2;
  }

  std::vector<canopen::RxFilter> filters{{canopen::cob::nmt, false}};
  for (auto id : ids) {
    filters.push_back({canopen::cob::sdo_rx + id, false});
    filters.push_back({canopen::cob::nmt_error_control + id, true});
  }

  std::optional<canopen::SocketCan> can;
  try {
    can.emplace(interface, filters);
  } catch (const std::system_error& e) {
    fmt::print(stderr, "fieldgate-sim-canopen: {}: {}\n", interface, e.what());
    return 1;
  }

  auto log = [verbose](const std::string& text) {
    if (verbose) fmt::print(stderr, "{}\n", text);
  };
  auto sink = [&](const canopen::CanFrame& frame) {
    if (verbose) fmt::print(stderr, "({}) {} {} tx\n", wall_time(), interface, to_string(frame));
    can->write(frame);
  };
  canopen::Network network(config, sink, verbose ? canopen::LogSink(log) : canopen::LogSink());
  for (auto id : ids) network.add_node(id, Clock::now());

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);
  sigset_t blocked, orig;
  sigemptyset(&blocked);
  sigaddset(&blocked, SIGINT);
  sigaddset(&blocked, SIGTERM);
  sigprocmask(SIG_BLOCK, &blocked, &orig);

  fmt::print("ready {} nodes {}\n", interface, nodes_text);
  std::fflush(stdout);

  bool stdin_open = true;
  std::string input;
  int rc = 0;
  try {
    while (!g_stop) {
      auto now = Clock::now();
      network.advance(now);
      can->flush();

      const auto deadline = network.next_deadline();
      auto wait = std::chrono::milliseconds(1000);
      if (deadline != canopen::TimePoint::max())
        wait = std::min(wait, std::chrono::ceil<std::chrono::milliseconds>(
                                  std::max(deadline - now, Clock::duration::zero())));
      if (can->pending() && !can->poll_for_writable())
        wait = std::min(wait, std::chrono::milliseconds(1));

      pollfd fds[2] = {{can->fd(), POLLIN, 0}, {STDIN_FILENO, POLLIN, 0}};
      if (can->pending() && can->poll_for_writable()) fds[0].events |= POLLOUT;
      const nfds_t nfds = stdin_open ? 2 : 1;
      const timespec ts{static_cast<time_t>(wait.count() / 1000),
                        static_cast<long>(wait.count() % 1000) * 1000000};
      if (ppoll(fds, nfds, &ts, &orig) < 0) {
        if (errno == EINTR) continue;
        throw std::system_error(errno, std::generic_category(), "ppoll");
      }

      if (fds[0].revents & (POLLIN | POLLERR)) {
        const auto downs = can->down_events();
        while (auto frame = can->read()) {
          if (verbose)
            fmt::print(stderr, "({}) {} {} rx\n", wall_time(), interface, to_string(*frame));
          network.receive(*frame, Clock::now());
        }
        if (can->down_events() != downs)
          fmt::print(stderr, "fieldgate-sim-canopen: {} is down\n", interface);
      }
      if (stdin_open && (fds[1].revents & (POLLIN | POLLHUP | POLLERR))) {
        char buf[4096];
        const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
        if (n <= 0) {
          if (n == 0 || (errno != EINTR && errno != EAGAIN)) stdin_open = false;
          continue;
        }
        input.append(buf, static_cast<std::size_t>(n));
        std::size_t nl;
        while ((nl = input.find('\n')) != std::string::npos) {
          const std::string line = input.substr(0, nl);
          input.erase(0, nl + 1);
          const auto result = network.execute(line, Clock::now());
          if (!result.message.empty()) {
            fmt::print("{}{}\n", result.ok ? "" : "error: ", result.message);
            std::fflush(stdout);
          }
          if (result.quit) g_stop = 1;
        }
      }
    }
  } catch (const std::system_error& e) {
    fmt::print(stderr, "fieldgate-sim-canopen: {}\n", e.what());
    rc = 1;
  }
  can->flush();
  if (can->dropped() > 0)
    fmt::print(stderr, "fieldgate-sim-canopen: {} frames dropped (transmit queue full)\n",
               can->dropped());
  return rc;
}
