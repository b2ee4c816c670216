#pragma once

// The one fake serial line of the in-process family tests: a ByteTransport whose far end (a
// simulator's I/O-free core, or a script) lives in the test process. Each write goes to the far
// end, which delivers bytes now or after a delay; a far end with its own clock (an exchange
// that times its replies) can be polled instead. Reads wait, on real time, for what is due.

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>
#include <chrono>
#include <deque>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "drivers/transport/byte_transport.hpp"

namespace fieldgate::test {

class FakeLine : public ByteTransport {
 public:
  using Clock = std::chrono::steady_clock;
  // What the far end makes of one write: it calls deliver() on the line.
  using FarEnd = std::function<void(std::string_view written)>;
  // A far end on its own schedule: appends to rx what has come due by now; tells when more will.
  struct Schedule {
    std::function<void(std::string& rx)> advance;
    std::function<std::optional<Clock::time_point>()> next_due;
  };

  FakeLine(asio::io_context& io, std::string description, double char_time_us)
      : description_(std::move(description)), char_time_us_(char_time_us), data_ready_(io) {}

  void set_far_end(FarEnd far_end) { far_end_ = std::move(far_end); }
  void set_schedule(Schedule schedule) { schedule_ = std::move(schedule); }
  // Bytes the far end sends, readable after `delay` (plus the line's reply delay, if any).
  void deliver(std::string bytes, Clock::duration delay = {}) {
    if (bytes.empty()) return;
    delay += reply_delay_;
    if (delay == Clock::duration::zero() && (!keep_order_ || late_.empty())) {
      rx_ += bytes;
    } else {
      auto due = Clock::now() + delay;
      if (keep_order_ && !late_.empty()) due = std::max(due, late_.back().first);
      auto at = std::upper_bound(late_.begin(), late_.end(), due,
                                 [](auto t, const auto& late) { return t < late.first; });
      late_.insert(at, {due, std::move(bytes)});
    }
    data_ready_.cancel();
  }
  // Delivered bytes arrive in the order delivered, whatever their delays (one wire from a
  // chain of units); otherwise each arrives when its own delay is up (an echo overtakes a
  // late reply).
  void keep_order() { keep_order_ = true; }
  // Everything delivered arrives this much later (a unit slower than the reply timeout).
  void set_reply_delay(std::chrono::milliseconds delay) { reply_delay_ = delay; }

  // Every write() as it was made: paced lines show up one character at a time.
  const std::vector<std::string>& writes() const { return writes_; }
  std::string all_written() const {
    std::string s;
    for (const auto& w : writes_) s += w;
    return s;
  }
  void clear_writes() { writes_.clear(); }

  asio::awaitable<std::error_code> open() override {
    open_ = true;
    ++opens_;
    co_return std::error_code{};
  }
  // How often open() was called (the line starts open, so a reopen counts 1).
  int opens() const { return opens_; }
  void close() override { open_ = false; }
  bool is_open() const override { return open_; }

  asio::awaitable<std::error_code> write(std::string_view bytes) override {
    writes_.emplace_back(bytes);
    if (far_end_) far_end_(bytes);
    data_ready_.cancel();
    co_return std::error_code{};
  }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    for (;;) {
      if (const std::size_t n = take(buffer)) co_return std::pair{std::error_code{}, n};
      data_ready_.expires_at(next_due());
      co_await data_ready_.async_wait(asio::as_tuple(asio::use_awaitable));
      arrive();
      // A cancelled read takes nothing, even if bytes came due meanwhile: its result is thrown
      // away (a read raced against a timeout), so what it took would be lost. They stay for the
      // next read, as a real port leaves them in the kernel.
      const auto state = co_await asio::this_coro::cancellation_state;
      if (state.cancelled() != asio::cancellation_type::none)
        co_return std::pair{std::make_error_code(std::errc::operation_canceled), std::size_t{0}};
    }
  }
  // As a port's output queue takes a short request: whole, at once (Link::send_ahead).
  std::size_t write_available(std::string_view bytes) override {
    if (!open_ || !write_ahead_) return 0;
    ++writes_ahead_;
    writes_.emplace_back(bytes);
    if (far_end_) far_end_(bytes);
    data_ready_.cancel();
    return bytes.size();
  }
  // How many writes were made without waiting (requests sent ahead).
  int writes_ahead() const { return writes_ahead_; }
  // A line that only writes by waiting: nothing can be sent ahead on it.
  void refuse_write_ahead() { write_ahead_ = false; }
  std::size_t read_available(asio::mutable_buffer buffer) override { return take(buffer); }
  void discard_input() override {
    arrive();
    rx_.clear();
  }
  std::string describe() const override { return description_; }
  double char_time_us() const override { return char_time_us_; }

 private:
  // Moves what has come due into rx_.
  void arrive() {
    while (!late_.empty() && late_.front().first <= Clock::now()) {
      rx_ += late_.front().second;
      late_.pop_front();
    }
    if (schedule_.advance) schedule_.advance(rx_);
  }
  std::size_t take(asio::mutable_buffer buffer) {
    arrive();
    const std::size_t n = std::min(buffer.size(), rx_.size());
    rx_.copy(static_cast<char*>(buffer.data()), n);
    rx_.erase(0, n);
    return n;
  }
  Clock::time_point next_due() const {
    auto due = late_.empty() ? Clock::time_point::max() : late_.front().first;
    if (schedule_.next_due)
      if (const auto d = schedule_.next_due()) due = std::min(due, *d);
    return due;
  }

  std::string description_;
  double char_time_us_;
  FarEnd far_end_;
  Schedule schedule_;
  std::chrono::milliseconds reply_delay_{0};
  std::deque<std::pair<Clock::time_point, std::string>> late_;
  asio::steady_timer data_ready_;
  std::string rx_;
  std::vector<std::string> writes_;
  bool open_ = true;
  int opens_ = 0;
  bool keep_order_ = false;
  bool write_ahead_ = true;
  int writes_ahead_ = 0;
};

// Runs one awaitable, and whatever else io has to do, to completion; throws if the awaitable
// never finished.
template <typename T>
T run(asio::io_context& io, asio::awaitable<T> work) {
  std::optional<T> result;
  asio::co_spawn(io, std::move(work), [&](std::exception_ptr e, T value) {
    if (e) std::rethrow_exception(e);
    result = std::move(value);
  });
  io.restart();
  io.run();
  if (!result) throw std::logic_error("the awaitable never finished");
  return std::move(*result);
}

inline void run(asio::io_context& io, asio::awaitable<void> work) {
  bool finished = false;
  asio::co_spawn(io, std::move(work), [&](std::exception_ptr e) {
    if (e) std::rethrow_exception(e);
    finished = true;
  });
  io.restart();
  io.run();
  if (!finished) throw std::logic_error("the awaitable never finished");
}

}  // namespace fieldgate::test
