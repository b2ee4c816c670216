#pragma once

// A ByteTransport whose far end is the simulator's party line, in process: the family's
// transact() runs against simulated units without a PTY. Replies the units delay (a queued
// index, S) arrive after their delay.

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <memory>
#include <string>
#include <vector>

#include "drivers/transport/byte_transport.hpp"
#include "sim/ims/party_line.hpp"

namespace fieldgate::test {

class ChainTransport final : public ByteTransport {
 public:
  ChainTransport(asio::io_context& io, sim::ims::PartyLineOptions options)
      : io_(io),
        chain_(
            std::move(options), faults_, [] { return sim::SimClock::now(); }, sim::SimClock::now()),
        data_ready_(io) {}

  sim::ims::PartyLine& chain() { return chain_; }
  sim::FaultInjection& faults() { return faults_; }
  // Every write() as it was made: paced lines show up one character at a time.
  const std::vector<std::string>& writes() const { return writes_; }
  void clear_writes() { writes_.clear(); }

  asio::awaitable<std::error_code> open() override {
    open_ = true;
    co_return std::error_code{};
  }
  void close() override { open_ = false; }
  bool is_open() const override { return open_; }

  asio::awaitable<std::error_code> write(std::string_view bytes) override {
    writes_.emplace_back(bytes);
    if (!faults_.silence) deliver(chain_.echo(bytes));
    pending_.append(bytes);
    while (const std::size_t n = sim::ims::PartyLine::frame(pending_)) {
      const std::string request = pending_.substr(0, n);
      pending_.erase(0, n);
      if (faults_.silence) continue;
      const sim::DeviceReply reply = chain_.respond(request, sim::SimClock::now());
      if (reply.bytes.empty()) continue;
      // `delay MS` of the control channel holds results and completions, not echoes.
      const auto delay = reply.extra_delay + faults_.reply_delay;
      if (delay.count() == 0) {
        deliver(reply.bytes);
      } else {
        auto timer = std::make_shared<asio::steady_timer>(io_, delay);
        timer->async_wait(
            [this, timer, bytes = reply.bytes](boost::system::error_code) { deliver(bytes); });
      }
    }
    co_return std::error_code{};
  }

  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    for (;;) {
      if (!rx_.empty()) {
        const std::size_t n = std::min(buffer.size(), rx_.size());
        rx_.copy(static_cast<char*>(buffer.data()), n);
        rx_.erase(0, n);
        co_return std::pair{std::error_code{}, n};
      }
      data_ready_.expires_at(asio::steady_timer::time_point::max());
      co_await data_ready_.async_wait(asio::as_tuple(asio::use_awaitable));
      const auto state = co_await asio::this_coro::cancellation_state;
      if (rx_.empty() && state.cancelled() != asio::cancellation_type::none)
        co_return std::pair{std::make_error_code(std::errc::operation_canceled), std::size_t{0}};
    }
  }

  std::size_t read_available(asio::mutable_buffer buffer) override {
    const std::size_t n = std::min(buffer.size(), rx_.size());
    rx_.copy(static_cast<char*>(buffer.data()), n);
    rx_.erase(0, n);
    return n;
  }
  void discard_input() override { rx_.clear(); }
  std::string describe() const override { return "simulated party line"; }
  double char_time_us() const override { return 1e6 * 10 / 9600; }

 private:
  void deliver(const std::string& bytes) {
    if (bytes.empty()) return;
    rx_ += bytes;
    data_ready_.cancel();
  }

  asio::io_context& io_;
  sim::FaultInjection faults_;
  sim::ims::PartyLine chain_;
  asio::steady_timer data_ready_;
  std::string rx_;
  std::string pending_;
  std::vector<std::string> writes_;
  bool open_ = true;
};

}  // namespace fieldgate::test
