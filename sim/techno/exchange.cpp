#include "sim/techno/exchange.hpp"

#include <poll.h>
#include <signal.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <system_error>

#include "sim/common/line_device_loop.hpp"

namespace fieldgate::sim::techno {
namespace {

volatile sig_atomic_t g_stop_signal = 0;

void on_stop_signal(int signal_number) {
  g_stop_signal = signal_number;
}

constexpr std::size_t kMaxLine = 4096;
constexpr std::size_t kMaxOutbox = 1 << 20;

}  // namespace

TechnoExchange::TechnoExchange(Controller& controller, ExchangeOptions options,
                               FaultInjection& faults)
    : controller_(controller), options_(options), faults_(faults), random_(options.seed) {
  controller_.set_emit([this](SimTime at, std::string bytes) { emit(at, std::move(bytes)); });
}

void TechnoExchange::receive(SimTime now, std::string_view bytes) {
  if (bytes.empty()) return;
  if (!log_epoch_) log_epoch_ = now;
  for (const char c : bytes) {
    if (c == '\xff' || c == '\xfe') {
      // The raw bytes act wherever they arrive, even in the middle of a line.
      SimTime at = now;
      if (!arrivals_.empty()) at = std::max(at, arrivals_.back().at);
      arrivals_.push_back({std::string(1, c), true, at});
      continue;
    }
    if (c == '\n' && rx_.empty() && drop_lf_) {
      drop_lf_ = false;  // "an LF may follow" the CR (p.29)
      continue;
    }
    drop_lf_ = false;
    if (c == '\r') {
      const SimTime at = receive_wire_.complete(rx_.size() + 1, now, options_.wire);
      arrivals_.push_back({std::move(rx_), false, at});
      rx_.clear();
      drop_lf_ = true;
      continue;
    }
    if (rx_.empty()) receive_wire_.first_byte(now);
    rx_ += c;
    if (rx_.size() > kMaxLine) {
      log(now, "overflow, discarded", rx_);
      rx_.clear();
    }
  }
}

void TechnoExchange::advance(SimTime now, std::string& out) {
  while (!arrivals_.empty() && arrivals_.front().at <= now) {
    const Arrival a = std::move(arrivals_.front());
    arrivals_.pop_front();
    if (faults_.silence) {
      log(a.at, "rx (silenced)", a.raw ? a.bytes : a.bytes + "\r");
      continue;
    }
    log(a.at, "rx", a.raw ? a.bytes : a.bytes + "\r");
    if (a.raw && a.bytes.front() == '\xff')
      controller_.stop_byte(a.at);
    else if (a.raw)
      controller_.reset_byte(a.at);
    else
      controller_.line(a.bytes, a.at);
  }
  controller_.advance(now);
  transmitter_.release(now, out);
}

std::optional<SimTime> TechnoExchange::next_deadline() const {
  std::optional<SimTime> deadline = transmitter_.next_due();
  const auto earliest = [&](std::optional<SimTime> t) {
    if (t) deadline = deadline ? std::min(*deadline, *t) : *t;
  };
  if (!arrivals_.empty()) earliest(arrivals_.front().at);
  earliest(controller_.next_event());
  return deadline;
}

void TechnoExchange::emit(SimTime at, std::string bytes) {
  std::string_view note = "tx";
  if (faults_.garbage_replies > 0) {
    --faults_.garbage_replies;
    std::uniform_int_distribution<int> byte(0x21, 0x7e);
    for (char& c : bytes)
      if (c != '\r') c = static_cast<char>(byte(random_));
    note = "tx (garbage)";
  } else if (faults_.truncated_replies > 0) {
    --faults_.truncated_replies;
    while (!bytes.empty() && bytes.back() == '\r') bytes.pop_back();
    bytes.resize(bytes.size() / 2);
    note = "tx (truncated)";
  }
  log(at, note, bytes);
  if (bytes.empty()) return;
  const SimTime start = at + options_.wire.turnaround + faults_.reply_delay;
  transmitter_.enqueue(start, bytes, options_.wire.enabled ? &options_.wire.timing : nullptr);
}

void TechnoExchange::log(SimTime now, std::string_view what, std::string_view bytes) const {
  if (!options_.verbose) return;
  const double t = log_epoch_ ? std::chrono::duration<double>(now - *log_epoch_).count() : 0.0;
  std::fprintf(stderr, "[%10.6f] techno %.*s \"%s\"\n", t, static_cast<int>(what.size()),
               what.data(), escape_bytes(bytes).c_str());
}

void run_techno_device(PtyPort& port, ControlChannel& control, TechnoExchange& exchange) {
  // Stop signals are blocked except inside ppoll(), so none slips in between the check and the
  // wait (as in run_line_device).
  struct sigaction action {};
  action.sa_handler = on_stop_signal;
  sigemptyset(&action.sa_mask);
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) ::sigaction(s, &action, nullptr);
  ::signal(SIGPIPE, SIG_IGN);
  sigset_t stop_signals;
  sigset_t wait_mask;
  sigemptyset(&stop_signals);
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&stop_signals, s);
  ::sigprocmask(SIG_BLOCK, &stop_signals, &wait_mask);
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) sigdelset(&wait_mask, s);

  std::string outbox;
  std::array<char, 4096> buffer{};
  while (!control.quit_requested() && g_stop_signal == 0) {
    SimTime now = SimClock::now();
    exchange.advance(now, outbox);
    if (!outbox.empty()) outbox.erase(0, port.write_some(outbox));
    if (outbox.size() > kMaxOutbox) outbox.clear();

    std::array<pollfd, 2> fds{};
    fds[0] = {port.master_fd(), static_cast<short>(POLLIN | (outbox.empty() ? 0 : POLLOUT)), 0};
    fds[1] = {control.input_fd(), POLLIN, 0};
    const nfds_t count = control.input_fd() >= 0 ? 2 : 1;

    timespec timeout{};
    timespec* timeout_ptr = nullptr;
    if (const auto deadline = exchange.next_deadline()) {
      const auto wait = std::max(SimClock::duration::zero(), *deadline - now);
      const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(wait).count();
      timeout.tv_sec = static_cast<time_t>(ns / 1'000'000'000);
      timeout.tv_nsec = static_cast<long>(ns % 1'000'000'000);
      timeout_ptr = &timeout;
    }
    const int ready = ::ppoll(fds.data(), count, timeout_ptr, &wait_mask);
    if (ready < 0) {
      if (errno == EINTR) continue;
      throw std::system_error(errno, std::generic_category(), "ppoll");
    }
    now = SimClock::now();
    if (fds[0].revents & POLLIN) {
      std::size_t n;
      while ((n = port.read_some(buffer)) > 0) exchange.receive(now, {buffer.data(), n});
    }
    if (count > 1 && (fds[1].revents & (POLLIN | POLLHUP | POLLERR))) control.on_readable();
  }
  ::sigprocmask(SIG_UNBLOCK, &stop_signals, nullptr);
}

}  // namespace fieldgate::sim::techno
