#include "sim/common/line_device_loop.hpp"

#include <poll.h>
#include <signal.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <system_error>

namespace fieldgate::sim {
namespace {

volatile sig_atomic_t g_stop_signal = 0;

void on_stop_signal(int signal_number) {
  g_stop_signal = signal_number;
}

// A host that never reads would otherwise grow the outbox without bound.
constexpr std::size_t kMaxOutbox = 1 << 20;

}  // namespace

std::string escape_bytes(std::string_view bytes) {
  std::string out;
  for (const char c : bytes) {
    switch (c) {
      case '\r':
        out += "\\r";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\\':
        out += "\\\\";
        break;
      default:
        if (c >= 0x20 && c < 0x7f) {
          out += c;
        } else {
          char hex[8];
          std::snprintf(hex, sizeof hex, "\\x%02x", static_cast<unsigned char>(c));
          out += hex;
        }
    }
  }
  return out;
}

LineExchange::LineExchange(LineDeviceHooks hooks, LineDeviceOptions options, FaultInjection& faults)
    : hooks_(std::move(hooks)),
      options_(std::move(options)),
      faults_(faults),
      random_(options_.seed) {}

void LineExchange::receive(SimTime now, std::string_view bytes) {
  if (bytes.empty()) return;
  if (!log_epoch_) log_epoch_ = now;
  if (hooks_.echo && !faults_.silence) {
    const std::string echoed = hooks_.echo(bytes);
    echoed_ += echoed.size();
    transmitter_.enqueue(now, echoed, options_.wire.enabled ? &options_.wire.timing : nullptr);
  }
  while (!bytes.empty()) {
    const std::size_t raw =
        hooks_.raw ? bytes.find_first_of(hooks_.raw_bytes) : std::string_view::npos;
    take(now, bytes.substr(0, raw));
    if (raw == std::string_view::npos) break;
    take_raw(now, bytes[raw]);
    bytes.remove_prefix(raw + 1);
  }
}

void LineExchange::take(SimTime now, std::string_view bytes) {
  if (bytes.empty()) return;
  const auto dropped = [&](char c) {
    return options_.dropped_after_request.find(c) != std::string::npos;
  };
  if (after_request_ && rx_.empty() && dropped(bytes.front())) bytes.remove_prefix(1);
  after_request_ = false;
  if (bytes.empty()) return;
  if (rx_.empty()) receive_wire_.first_byte(now);
  rx_.append(bytes);
  while (!rx_.empty()) {
    const std::size_t length = hooks_.frame(rx_);
    if (length == 0) break;
    const SimTime started = receive_wire_.started();
    const SimTime arrived = receive_wire_.complete(length, now, options_.wire);
    requests_.push_back({rx_.substr(0, length), arrived, started, echoed_, false});
    echoed_ = 0;
    rx_.erase(0, length);
    after_request_ = rx_.empty();
    if (!rx_.empty() && dropped(rx_.front())) rx_.erase(0, 1);
  }
  if (rx_.size() > options_.max_pending) {
    log(now, "overflow, discarded", rx_);
    rx_.clear();
  }
}

void LineExchange::take_raw(SimTime now, char byte) {
  // No wire time of its own, but it cannot overtake what arrived before it.
  SimTime at = now;
  if (!requests_.empty()) at = std::max(at, requests_.back().arrived);
  requests_.push_back({std::string(1, byte), at, at, 0, true});
}

void LineExchange::advance(SimTime now, std::string& out) {
  while (!requests_.empty() && requests_.front().arrived <= now) {
    const PendingRequest request = std::move(requests_.front());
    requests_.pop_front();
    // Run it at the instant it arrived, so a late wake-up does not delay the reply schedule.
    execute(request, request.arrived);
  }
  if (hooks_.advance) hooks_.advance(now);
  transmitter_.release(now, out);
}

void LineExchange::emit(SimTime at, std::string_view bytes) {
  if (!log_epoch_) log_epoch_ = at;
  send(at, {}, bytes, {});
}

std::optional<SimTime> LineExchange::next_deadline() const {
  std::optional<SimTime> deadline = transmitter_.next_due();
  if (!requests_.empty()) {
    const SimTime arrived = requests_.front().arrived;
    deadline = deadline ? std::min(*deadline, arrived) : arrived;
  }
  if (hooks_.next_event) {
    if (const auto event = hooks_.next_event())
      deadline = deadline ? std::min(*deadline, *event) : *event;
  }
  return deadline;
}

void LineExchange::execute(const PendingRequest& request, SimTime now) {
  if (faults_.silence) {
    log(now, "rx (silenced)", request.bytes);
    return;
  }
  log(now, "rx", request.bytes);
  const DeviceReply reply =
      request.raw ? hooks_.raw(request.bytes.front(), now) : hooks_.respond(request.bytes, now);
  if (options_.wire_log) {
    const auto ns = [](SimTime t) {
      return static_cast<long long>(
          std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count());
    };
    std::fprintf(options_.wire_log, "%lld %lld %zu %zu %zu %lld %s\n", ns(request.started),
                 ns(request.arrived), request.bytes.size(), request.echoed, reply.bytes.size(),
                 static_cast<long long>((options_.wire.turnaround + reply.extra_delay).count()),
                 escape_bytes(request.bytes).c_str());
    std::fflush(options_.wire_log);
  }
  if (reply.new_baud) {
    options_.wire.timing.set_baud(*reply.new_baud);
    log(now, "baud " + std::to_string(*reply.new_baud), {});
  }
  send(now, request.bytes, reply.bytes, reply.extra_delay);
}

void LineExchange::send(SimTime now, std::string_view request, std::string_view reply,
                        std::chrono::microseconds extra_delay) {
  if (reply.empty()) {
    journal(now, request, {}, {});
    log(now, "tx (no reply)", {});
    return;
  }
  std::string bytes(reply);
  std::string_view note = "tx";
  auto delay = faults_.reply_delay;
  std::string_view chaos_fault;
  if (faults_.chaos.on) {
    if (chaos_generation_ != faults_.chaos.generation) {
      chaos_generation_ = faults_.chaos.generation;
      chaos_random_.seed(faults_.chaos.seed);
    }
    const auto& c = faults_.chaos;
    const unsigned roll = std::uniform_int_distribution<unsigned>(0, 99)(chaos_random_);
    if (roll < c.late_percent) {
      chaos_fault = "late";
      delay += c.late;
    } else if (roll < c.late_percent + c.drop_percent) {
      chaos_fault = "dropped";
    } else if (roll < c.late_percent + c.drop_percent + c.garble_percent) {
      chaos_fault = "garbled";
    } else if (roll < c.late_percent + c.drop_percent + c.garble_percent + c.truncate_percent) {
      chaos_fault = "truncated";
    }
  }
  if (!faults_.swallow_reply_to.empty() &&
      request.find(faults_.swallow_reply_to) != std::string_view::npos) {
    faults_.swallow_reply_to.clear();
    chaos_fault = "swallowed";
  }
  journal(now, request, reply, chaos_fault);
  if (chaos_fault == "dropped" || chaos_fault == "swallowed") {
    log(now, chaos_fault == "dropped" ? "tx (dropped)" : "tx (swallowed)", bytes);
    return;
  }
  if (chaos_fault == "garbled") {
    bytes = garbage(bytes);
    note = "tx (garbage)";
  } else if (chaos_fault == "truncated") {
    bytes = truncated(bytes);
    note = "tx (truncated)";
  } else if (faults_.garbage_replies > 0) {
    --faults_.garbage_replies;
    bytes = garbage(bytes);
    note = "tx (garbage)";
  } else if (faults_.truncated_replies > 0) {
    --faults_.truncated_replies;
    bytes = truncated(bytes);
    note = "tx (truncated)";
  }
  const SimTime start = now + options_.wire.turnaround + delay + extra_delay;
  transmitter_.enqueue(start, bytes, options_.wire.enabled ? &options_.wire.timing : nullptr);
  log(now, note, bytes);
}

void LineExchange::journal(SimTime now, std::string_view request, std::string_view reply,
                           std::string_view fault) {
  if (options_.journal == nullptr) return;
  const auto us =
      std::chrono::duration_cast<std::chrono::microseconds>(now - log_epoch_.value_or(now)).count();
  std::fprintf(options_.journal, "%lld %s -> %s%s%s\n", static_cast<long long>(us),
               escape_bytes(request).c_str(), escape_bytes(reply).c_str(), fault.empty() ? "" : " ",
               std::string(fault).c_str());
  std::fflush(options_.journal);
}

std::string LineExchange::garbage(std::string_view reply) {
  // Same length as the real reply and still terminated, so the host sees a complete line it
  // cannot parse; `truncate` covers the missing-terminator case. No blanks (a host may take
  // them for padding: a garbled Whedco prompt " *" would be a prompt), and a first byte above
  // ASCII, which no reply of these families carries: garbage that happened to spell a valid
  // reply would be no garbage.
  std::string out;
  std::string_view body = reply;
  std::string_view terminator;
  while (!body.empty() && options_.terminators.find(body.back()) != std::string::npos) {
    terminator = reply.substr(body.size() - 1);
    body.remove_suffix(1);
  }
  std::uniform_int_distribution<int> byte(0, 255);
  const std::size_t length = std::max<std::size_t>(1, body.size());
  while (out.size() < length) {
    const char c = static_cast<char>(byte(random_));
    if (options_.terminators.find(c) == std::string::npos && c != ' ' && c != '\t') out += c;
  }
  out[0] = static_cast<char>(static_cast<unsigned char>(out[0]) | 0x80);
  out += terminator;
  return out;
}

std::string LineExchange::truncated(std::string_view reply) const {
  while (!reply.empty() && options_.terminators.find(reply.back()) != std::string::npos) {
    reply.remove_suffix(1);
  }
  return std::string(reply.substr(0, reply.size() / 2));
}

void LineExchange::log(SimTime now, std::string_view what, std::string_view bytes) const {
  if (!options_.verbose) return;
  const double t = log_epoch_ ? std::chrono::duration<double>(now - *log_epoch_).count() : 0.0;
  std::fprintf(stderr, "[%10.6f] %s %.*s %s%s%s\n", t, options_.name.c_str(),
               static_cast<int>(what.size()), what.data(), bytes.empty() ? "" : "\"",
               escape_bytes(bytes).c_str(), bytes.empty() ? "" : "\"");
}

void run_line_device(PtyPort& port, ControlChannel& control, LineExchange& exchange) {
  // Stop signals are blocked except inside ppoll(), so one cannot slip in between the check of
  // g_stop_signal and the wait.
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

}  // namespace fieldgate::sim
