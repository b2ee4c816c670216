#pragma once

// A ByteTransport for running WhedcoFamily::transact() in process: every write goes to a
// responder (the simulated CMC line, or a script), whose answer becomes readable at once.

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <deque>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "drivers/link.hpp"
#include "drivers/transport/byte_transport.hpp"
#include "sim/whedco/cmc_line.hpp"

namespace fieldgate::test {

class LineTransport final : public ByteTransport {
 public:
  using Responder = std::function<std::string(std::string_view written)>;

  LineTransport(asio::io_context& io, Responder responder)
      : responder_(std::move(responder)), data_ready_(io) {}

  // The simulated line: echo as the bytes arrive, then each complete request's reply.
  static Responder simulated(sim::whedco::CmcLine& line) {
    return [&line, pending = std::string()](std::string_view written) mutable {
      std::string out = line.echo(written);
      pending.append(written);
      while (const std::size_t n = sim::whedco::CmcLine::frame(pending)) {
        out += line.handle(pending.substr(0, n), sim::SimClock::now()).bytes;
        pending.erase(0, n);
      }
      return out;
    };
  }

  // Canned replies, one per write, in order; writes beyond the script get silence.
  static Responder scripted(std::deque<std::string> replies) {
    return [replies = std::move(replies)](std::string_view) mutable {
      if (replies.empty()) return std::string();
      std::string r = replies.front();
      replies.pop_front();
      return r;
    };
  }

  const std::vector<std::string>& writes() const { return writes_; }

  asio::awaitable<std::error_code> open() override { co_return std::error_code{}; }
  void close() override {}
  bool is_open() const override { return true; }
  // Replies arrive this much after their request (a unit slower than the reply timeout).
  void set_reply_delay(std::chrono::milliseconds delay) { delay_ = delay; }

  asio::awaitable<std::error_code> write(std::string_view bytes) override {
    writes_.emplace_back(bytes);
    std::string out = responder_(bytes);
    if (delay_.count() == 0)
      rx_ += out;
    else if (!out.empty())
      late_.push_back({std::chrono::steady_clock::now() + delay_, std::move(out)});
    data_ready_.cancel();
    co_return std::error_code{};
  }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    for (;;) {
      arrive();
      if (!rx_.empty()) {
        const std::size_t n = std::min(buffer.size(), rx_.size());
        rx_.copy(static_cast<char*>(buffer.data()), n);
        rx_.erase(0, n);
        co_return std::pair{std::error_code{}, n};
      }
      data_ready_.expires_at(late_.empty() ? asio::steady_timer::time_point::max()
                                           : late_.front().first);
      co_await data_ready_.async_wait(asio::as_tuple(asio::use_awaitable));
      arrive();
      const auto state = co_await asio::this_coro::cancellation_state;
      if (rx_.empty() && state.cancelled() != asio::cancellation_type::none)
        co_return std::pair{std::make_error_code(std::errc::operation_canceled), std::size_t{0}};
    }
  }
  void discard_input() override {
    arrive();
    rx_.clear();
  }
  std::string describe() const override { return "in-process CMC line"; }
  double char_time_us() const override { return 1e6 * 10 / 38400; }

 private:
  void arrive() {
    while (!late_.empty() && late_.front().first <= std::chrono::steady_clock::now()) {
      rx_ += late_.front().second;
      late_.pop_front();
    }
  }

  Responder responder_;
  std::chrono::milliseconds delay_{0};
  std::deque<std::pair<std::chrono::steady_clock::time_point, std::string>> late_;
  asio::steady_timer data_ready_;
  std::string rx_;
  std::vector<std::string> writes_;
};

// Runs one awaitable to completion.
template <typename T>
T run(asio::io_context& io, asio::awaitable<T> work) {
  std::optional<T> result;
  asio::co_spawn(io, std::move(work), [&](std::exception_ptr e, T value) {
    if (e) std::rethrow_exception(e);
    result = std::move(value);
  });
  io.restart();
  io.run();
  return std::move(*result);
}

inline void run(asio::io_context& io, asio::awaitable<void> work) {
  asio::co_spawn(io, std::move(work), [](std::exception_ptr e) {
    if (e) std::rethrow_exception(e);
  });
  io.restart();
  io.run();
}

}  // namespace fieldgate::test
