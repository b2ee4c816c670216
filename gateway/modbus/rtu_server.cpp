#include "gateway/modbus/rtu_server.hpp"

#include <linux/serial.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <deque>
#include <list>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/experimental/awaitable_operators.hpp>
#include <boost/asio/serial_port.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/write.hpp>

#include "gateway/modbus/rtu_codec.hpp"

namespace fieldgate::modbus {

using Clock = std::chrono::steady_clock;
using Bytes = std::vector<std::uint8_t>;
using namespace asio::experimental::awaitable_operators;

namespace {

constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);

bool is_write(std::uint8_t function) {
  return function == 0x05 || function == 0x06 || function == 0x0F || function == 0x10 ||
         function == 0x17;
}

// A request being answered. Writes are listed while they run, so a retry can find them.
struct Pending {
  Pending(asio::any_io_executor executor, std::uint8_t u, Bytes p)
      : unit(u), pdu(std::move(p)), ack_timer(std::move(executor)) {}
  std::uint8_t unit;
  Bytes pdu;
  std::uint64_t frame = 0;  // the frame (by number) the answer goes to
  Clock::time_point answer_by;
  bool answered = false;  // the master got an answer (the result or 0x05)
  bool done = false;
  bool acking = false;  // an acknowledger waits on ack_timer
  asio::steady_timer ack_timer;
};

}  // namespace

ModbusRtuServerOptions::Duration ModbusRtuServerOptions::silent_interval() const {
  if (frame_gap > Duration::zero()) return frame_gap;
  return rtu_silent_interval(serial.baud, serial.bits_per_character());
}

ModbusRtuServerOptions::Duration ModbusRtuServerOptions::answer_window() const {
  const Duration character = rtu_character_time(serial.baud, serial.bits_per_character());
  const Duration guard = std::max(
      {Duration(response_timeout / 10), Duration(std::chrono::milliseconds(5)), character});
  return std::max(Duration::zero(), response_timeout - guard);
}

class ModbusRtuServer::Impl : public std::enable_shared_from_this<Impl> {
 public:
  Impl(asio::any_io_executor executor, ModbusRtuServerOptions options,
       std::shared_ptr<RequestHandler> handler)
      : executor_(std::move(executor)),
        options_(std::move(options)),
        handler_(std::move(handler)),
        port_(executor_),
        frame_timer_(executor_),
        reopen_timer_(executor_) {}

  void start() {
    if (started_ || stopped_) return;
    started_ = true;
    // Named locals: GCC 12 destroys class-type prvalue arguments of a coroutine twice.
    auto self = shared_from_this();
    asio::co_spawn(executor_, run(self), asio::detached);
  }

  void stop() {
    if (stopped_) return;
    stopped_ = true;
    close_port();
    reopen_timer_.cancel();
    frame_timer_.cancel();
    for (auto& p : pending_) p->ack_timer.cancel();
  }

  void set_handler(std::shared_ptr<RequestHandler> handler) { handler_ = std::move(handler); }

  bool reconfigure(ModbusRtuServerOptions options) {
    if (!(options.serial == options_.serial) || !(options.rs485 == options_.rs485)) return false;
    options_ = std::move(options);
    return true;
  }

  const ModbusRtuServerOptions& options() const { return options_; }
  const ModbusRtuServerStats& stats() const { return stats_; }
  const std::string& last_error() const { return last_error_; }

 private:
  void report(const std::function<void(const std::string&)>& sink, const std::string& text) {
    if (sink) sink(text);
  }

  void close_port() {
    boost::system::error_code ignored;
    port_.close(ignored);
    stats_.link_up = false;
  }

  // Opens and sets up the port; on failure the reason is in last_error_.
  bool open_port() {
    const auto& s = options_.serial;
    const std::string where = "modbus rtu: " + s.device;
    boost::system::error_code ec;
    port_.open(s.device, ec);
    if (ec) {
      last_error_ = where + ": cannot open: " + ec.message();
      return false;
    }
    using sp = asio::serial_port_base;
    const sp::parity::type parity = s.parity == 'E'   ? sp::parity::even
                                    : s.parity == 'O' ? sp::parity::odd
                                                      : sp::parity::none;
    port_.set_option(sp::baud_rate(s.baud), ec);
    if (!ec) port_.set_option(sp::character_size(s.data_bits), ec);
    if (!ec) port_.set_option(sp::parity(parity), ec);
    if (!ec)
      port_.set_option(sp::stop_bits(s.stop_bits == 2 ? sp::stop_bits::two : sp::stop_bits::one),
                       ec);
    if (!ec) port_.set_option(sp::flow_control(sp::flow_control::none), ec);
    if (ec) {
      last_error_ = where + ": cannot set " + std::to_string(s.baud) + " baud " +
                    std::to_string(s.data_bits) + s.parity + std::to_string(s.stop_bits) + ": " +
                    ec.message();
      close_port();
      return false;
    }
    if (options_.rs485.enabled) {
      serial_rs485 rs{};
      rs.flags = SER_RS485_ENABLED | (options_.rs485.rts_high_on_send ? SER_RS485_RTS_ON_SEND
                                                                      : SER_RS485_RTS_AFTER_SEND);
      rs.delay_rts_before_send = static_cast<__u32>(options_.rs485.delay_before_send.count());
      rs.delay_rts_after_send = static_cast<__u32>(options_.rs485.delay_after_send.count());
      if (::ioctl(port_.native_handle(), TIOCSRS485, &rs) != 0) {
        last_error_ = where +
                      ": RS-485 direction control (TIOCSRS485) failed: " + std::strerror(errno) +
                      ". The port's driver does not switch RS-485 direction itself; use a port "
                      "or adapter that does (or one with automatic direction control and rs485 "
                      "enabled: false)";
        close_port();
        return false;
      }
    }
    ::tcflush(port_.native_handle(), TCIOFLUSH);
    last_error_.clear();
    return true;
  }

  asio::awaitable<void> run([[maybe_unused]] std::shared_ptr<Impl> self) {
    Clock::duration backoff = options_.reopen_min;
    while (!stopped_) {
      if (open_port()) {
        ++stats_.opens;
        stats_.link_up = true;
        backoff = options_.reopen_min;
        report(options_.notice, describe());
        rx_.clear();
        overflow_ = false;
        co_await (receive() || frame_watch());
        close_port();
        if (stopped_) co_return;
        report(options_.warning, last_error_);
      } else {
        report(options_.warning, last_error_ + "; retrying");
      }
      reopen_timer_.expires_after(backoff);
      co_await reopen_timer_.async_wait(use_tuple);
      backoff = std::min(backoff * 2, options_.reopen_max);
    }
  }

  std::string describe() const {
    const auto& s = options_.serial;
    return "modbus rtu: serving on " + s.device + " at " + std::to_string(s.baud) + " baud " +
           std::to_string(s.data_bits) + s.parity + std::to_string(s.stop_bits) +
           (options_.rs485.enabled ? ", RS-485 direction by the kernel" : "");
  }

  void take(const std::uint8_t* data, std::size_t n) {
    stats_.bytes_received += n;
    last_rx_ = Clock::now();
    const std::size_t room = rtu_max_adu_size + 1 - std::min(rx_.size(), rtu_max_adu_size + 1);
    if (n > room) overflow_ = true;
    rx_.insert(rx_.end(), data, data + std::min(n, room));
    frame_timer_.expires_at(last_rx_ + options_.silent_interval());
  }

  asio::awaitable<void> receive() {
    std::array<std::uint8_t, 512> buffer;
    for (;;) {
      auto [ec, n] = co_await port_.async_read_some(asio::buffer(buffer), use_tuple);
      if (ec) {
        last_error_ = "modbus rtu: " + options_.serial.device + ": read failed: " + ec.message();
        co_return;
      }
      take(buffer.data(), n);
    }
  }

  // Ends a frame when the line has been silent for t3.5.
  asio::awaitable<void> frame_watch() {
    frame_timer_.expires_at(Clock::time_point::max());
    for (;;) {
      auto [ec] = co_await frame_timer_.async_wait(use_tuple);
      // Bound to a local: GCC 12 miscompiles the co_await inside an if condition.
      const asio::cancellation_state state = co_await asio::this_coro::cancellation_state;
      if (state.cancelled() != asio::cancellation_type::none || stopped_) co_return;
      if (ec) continue;  // a new byte moved the deadline
      if (rx_.empty() || Clock::now() < last_rx_ + options_.silent_interval()) continue;
      if (!overflow_ && rtu_request_incomplete(rx_) &&
          Clock::now() < last_rx_ + options_.incomplete_frame_wait) {
        frame_timer_.expires_at(last_rx_ + options_.incomplete_frame_wait);
        continue;
      }
      // Bytes the kernel holds but the reader has not been woken for are part of this frame.
      int pending = 0;
      if (::ioctl(port_.native_handle(), FIONREAD, &pending) == 0 && pending > 0) {
        std::array<std::uint8_t, 512> buffer;
        const auto n = ::read(port_.native_handle(), buffer.data(),
                              std::min<std::size_t>(buffer.size(), std::size_t(pending)));
        if (n > 0) {
          take(buffer.data(), static_cast<std::size_t>(n));
          continue;
        }
      }
      Bytes frame;
      frame.swap(rx_);
      const bool overflow = overflow_;
      overflow_ = false;
      frame_timer_.expires_at(Clock::time_point::max());
      // A host too busy to read in time sees back-to-back requests as one: a leading request
      // that is complete by its own length and CRC is taken apart from the rest.
      std::span<const std::uint8_t> rest(frame);
      while (!overflow) {
        const auto size = rtu_request_size(rest);
        if (!size || *size >= rest.size() ||
            decode_rtu_adu(rest.first(*size)).error != RtuFrameError::none)
          break;
        // Followed by another request: the master no longer waits for its answer.
        handle_frame(rest.first(*size), false, last_rx_, false);
        rest = rest.subspan(*size);
      }
      handle_frame(rest, overflow, last_rx_);
    }
  }

  void handle_frame(std::span<const std::uint8_t> bytes, bool overflow, Clock::time_point end,
                    bool answerable = true) {
    ++frame_number_;  // whatever it is, the master is not waiting for an earlier answer now
    const RtuDecodeResult decoded =
        overflow ? RtuDecodeResult{RtuFrameError::too_long, {}} : decode_rtu_adu(bytes);
    if (decoded.error != RtuFrameError::none && options_.debug) {
      static constexpr char hex[] = "0123456789abcdef";
      std::string text;
      for (std::size_t i = 0; i < bytes.size() && i < 64; ++i)
        text += std::string(i ? " " : "") + hex[bytes[i] >> 4] + hex[bytes[i] & 15];
      options_.debug("modbus rtu: dropped a " + std::to_string(bytes.size()) + "-byte frame (" +
                     std::string(to_string(decoded.error)) + "): " + text +
                     (bytes.size() > 64 ? " ..." : ""));
    }
    if (decoded.error == RtuFrameError::bad_crc) {
      ++stats_.crc_errors;
      return;
    }
    if (decoded.error != RtuFrameError::none) {
      ++stats_.framing_errors;
      return;
    }
    const std::uint8_t unit = decoded.frame.unit;
    Bytes pdu(decoded.frame.pdu.begin(), decoded.frame.pdu.end());
    if (unit == rtu_broadcast_unit) {
      broadcast(pdu);
      return;
    }
    if (!options_.units.test(unit)) {
      ++stats_.other_units;
      return;
    }
    ++stats_.frames_ok;
    ++stats_.functions[pdu[0]].requests;
    auto self = shared_from_this();
    const Clock::time_point answer_by = end + options_.answer_window();
    // Frame 0 is never the latest: a request that is not answerable runs, unanswered.
    const std::uint64_t frame = answerable ? frame_number_ : 0;
    asio::co_spawn(executor_, answer(self, frame, unit, pdu, answer_by), asio::detached);
  }

  // The master still waits for this frame's answer: it sent nothing since and its time is
  // not up.
  bool still_awaited(std::uint64_t frame, Clock::time_point answer_by) const {
    return line_quiet_since(frame) && Clock::now() <= answer_by;
  }
  bool line_quiet_since(std::uint64_t frame) const {
    return frame == frame_number_ && rx_.empty() && port_.is_open();
  }

  void count_response(const Bytes& response) {
    if (response[0] & 0x80) {
      ++stats_.functions[response[0] & 0x7F].exceptions;
      ++stats_.exceptions_by_code[response[1]];
    }
  }

  asio::awaitable<void> answer([[maybe_unused]] std::shared_ptr<Impl> self, std::uint64_t frame,
                               std::uint8_t unit, Bytes pdu, Clock::time_point answer_by) {
    const std::uint8_t function = pdu[0];
    if (is_write(function)) {
      for (const auto& p : pending_) {
        if (!p->answered && !p->done && p->unit == unit && p->pdu == pdu) {
          ++stats_.retries_joined;
          p->frame = frame;
          p->answer_by = answer_by;
          arm_acknowledge(p);
          co_return;
        }
      }
    }
    const std::shared_ptr<RequestHandler> handler = handler_;
    if (!handler) {
      const Bytes response = encode_exception(function, ExceptionCode::gateway_path_unavailable);
      count_response(response);
      if (still_awaited(frame, answer_by)) send(unit, response);
      co_return;
    }
    auto pending = std::make_shared<Pending>(executor_, unit, std::move(pdu));
    pending->frame = frame;
    pending->answer_by = answer_by;
    std::list<std::shared_ptr<Pending>>::iterator listed = pending_.end();
    if (is_write(function)) {
      listed = pending_.insert(pending_.end(), pending);
      arm_acknowledge(pending);
    }
    const std::span<const std::uint8_t> request(pending->pdu);
    const Bytes response = co_await dispatch(*handler, unit, request);
    pending->done = true;
    pending->ack_timer.cancel();
    if (listed != pending_.end()) pending_.erase(listed);
    count_response(response);
    if (pending->answered) co_return;
    if (still_awaited(pending->frame, pending->answer_by)) {
      pending->answered = true;
      send(unit, response);
    } else {
      ++stats_.answers_dropped;
    }
  }

  void arm_acknowledge(const std::shared_ptr<Pending>& pending) {
    if (options_.slow_writes != SlowWrites::acknowledge) return;
    pending->ack_timer.expires_at(pending->answer_by);
    if (pending->acking) return;
    pending->acking = true;
    auto self = shared_from_this();
    asio::co_spawn(executor_, acknowledge(self, pending), asio::detached);
  }

  asio::awaitable<void> acknowledge([[maybe_unused]] std::shared_ptr<Impl> self,
                                    std::shared_ptr<Pending> pending) {
    for (;;) {
      auto [ec] = co_await pending->ack_timer.async_wait(use_tuple);
      if (pending->done || stopped_) break;
      if (ec || Clock::now() < pending->answer_by) continue;  // a retry moved the deadline
      // Sent at answer_by, which leaves the guard for it to reach the master.
      if (!pending->answered && line_quiet_since(pending->frame)) {
        pending->answered = true;
        ++stats_.acknowledged;
        ++stats_.exceptions_by_code[static_cast<std::uint8_t>(ExceptionCode::acknowledge)];
        send(pending->unit, encode_exception(pending->pdu[0], ExceptionCode::acknowledge));
      }
      break;
    }
    pending->acking = false;
  }

  void broadcast(const Bytes& pdu) {
    const BroadcastStop& stop = options_.broadcast;
    const auto parsed = parse_request(pdu);
    bool is_stop = false;
    if (const auto* request = std::get_if<Request>(&parsed)) {
      if (const auto* r = std::get_if<WriteSingleRegisterRequest>(request))
        is_stop = r->address == stop.address && r->value == stop.value;
      if (const auto* r = std::get_if<WriteRegistersRequest>(request))
        is_stop = r->address == stop.address && r->values.size() == 1 && r->values[0] == stop.value;
    }
    const std::shared_ptr<RequestHandler> handler = handler_;
    if (!is_stop || stop.writes.empty() || !handler) {
      ++stats_.broadcasts_dropped;
      return;
    }
    ++stats_.broadcasts_accepted;
    auto self = shared_from_this();
    for (const auto& w : stop.writes)
      asio::co_spawn(executor_, broadcast_write(self, handler, w.unit, stop.address, w.value),
                     asio::detached);
  }

  asio::awaitable<void> broadcast_write([[maybe_unused]] std::shared_ptr<Impl> self,
                                        std::shared_ptr<RequestHandler> handler, std::uint8_t unit,
                                        std::uint16_t address, std::uint16_t value) {
    const std::span<const std::uint16_t> values(&value, 1);
    const WriteResult result = co_await handler->write_registers(unit, address, values);
    if (!result.ok()) {
      ++stats_.broadcast_write_failures;
      report(options_.warning, "modbus rtu: broadcast stop: unit " + std::to_string(unit) +
                                   ": writing " + std::to_string(value) + " to register " +
                                   std::to_string(address) +
                                   " failed: " + std::string(to_string(result.exception())));
    }
  }

  void send(std::uint8_t unit, const Bytes& pdu) {
    Bytes adu;
    encode_rtu_adu(unit, pdu, adu);
    tx_.push_back(std::move(adu));
    if (!sending_) {
      sending_ = true;
      auto self = shared_from_this();
      asio::co_spawn(executor_, transmit(self), asio::detached);
    }
  }

  asio::awaitable<void> transmit([[maybe_unused]] std::shared_ptr<Impl> self) {
    while (!tx_.empty()) {
      const Bytes adu = std::move(tx_.front());
      tx_.pop_front();
      auto [ec, n] = co_await asio::async_write(port_, asio::buffer(adu), use_tuple);
      stats_.bytes_sent += n;
      // A failed write also fails the reader, which reopens the port.
      if (ec) tx_.clear();
    }
    sending_ = false;
  }

  asio::any_io_executor executor_;
  ModbusRtuServerOptions options_;
  std::shared_ptr<RequestHandler> handler_;
  asio::serial_port port_;
  asio::steady_timer frame_timer_;
  asio::steady_timer reopen_timer_;
  Bytes rx_;
  bool overflow_ = false;
  Clock::time_point last_rx_{};
  std::uint64_t frame_number_ = 0;
  std::list<std::shared_ptr<Pending>> pending_;
  std::deque<Bytes> tx_;
  bool sending_ = false;
  ModbusRtuServerStats stats_;
  std::string last_error_ = "not started";
  bool started_ = false;
  bool stopped_ = false;
};

ModbusRtuServer::ModbusRtuServer(asio::any_io_executor executor, ModbusRtuServerOptions options,
                                 std::shared_ptr<RequestHandler> handler)
    : impl_(std::make_shared<Impl>(std::move(executor), std::move(options), std::move(handler))) {}

ModbusRtuServer::~ModbusRtuServer() {
  impl_->stop();
}
void ModbusRtuServer::start() {
  impl_->start();
}
void ModbusRtuServer::stop() {
  impl_->stop();
}
void ModbusRtuServer::set_handler(std::shared_ptr<RequestHandler> handler) {
  impl_->set_handler(std::move(handler));
}
bool ModbusRtuServer::reconfigure(ModbusRtuServerOptions options) {
  return impl_->reconfigure(std::move(options));
}
const ModbusRtuServerOptions& ModbusRtuServer::options() const {
  return impl_->options();
}
const ModbusRtuServerStats& ModbusRtuServer::stats() const {
  return impl_->stats();
}
const std::string& ModbusRtuServer::last_error() const {
  return impl_->last_error();
}

}  // namespace fieldgate::modbus
