#pragma once

// A ByteTransport that connects TechnoFamily::transact() to the simulator's I/O-free exchange in
// process, on real time: writes go to the exchange, reads return its replies when they are due
// (a capital move's handshake only once the simulated motion has ended).

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <string>
#include <vector>

#include "drivers/transport/byte_transport.hpp"
#include "sim/techno/exchange.hpp"

namespace fieldgate::test {

class SimTransport final : public ByteTransport {
 public:
  SimTransport(asio::io_context& io, sim::techno::TechnoExchange& exchange)
      : exchange_(exchange), wake_(io) {}

  const std::vector<std::string>& writes() const { return writes_; }
  std::string all_written() const {
    std::string s;
    for (const auto& w : writes_) s += w;
    return s;
  }

  asio::awaitable<std::error_code> open() override { co_return std::error_code{}; }
  void close() override {}
  bool is_open() const override { return true; }
  asio::awaitable<std::error_code> write(std::string_view bytes) override {
    writes_.emplace_back(bytes);
    exchange_.receive(sim::SimClock::now(), bytes);
    wake_.cancel();
    co_return std::error_code{};
  }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    for (;;) {
      exchange_.advance(sim::SimClock::now(), rx_);
      if (!rx_.empty()) {
        const std::size_t n = std::min(buffer.size(), rx_.size());
        rx_.copy(static_cast<char*>(buffer.data()), n);
        rx_.erase(0, n);
        co_return std::pair{std::error_code{}, n};
      }
      const auto due = exchange_.next_deadline();
      wake_.expires_at(due ? *due : asio::steady_timer::time_point::max());
      co_await wake_.async_wait(asio::as_tuple(asio::use_awaitable));
      const auto state = co_await asio::this_coro::cancellation_state;
      if (state.cancelled() != asio::cancellation_type::none)
        co_return std::pair{std::make_error_code(std::errc::operation_canceled), std::size_t{0}};
    }
  }
  void discard_input() override {
    exchange_.advance(sim::SimClock::now(), rx_);
    rx_.clear();
  }
  std::string describe() const override { return "in-process techno simulator"; }
  double char_time_us() const override { return 0; }

 private:
  sim::techno::TechnoExchange& exchange_;
  asio::steady_timer wake_;
  std::string rx_;
  std::vector<std::string> writes_;
};

}  // namespace fieldgate::test
