// An in-memory CAN channel with the CANopen simulator's nodes behind it, like Lely's io2 vcan:
// the CAN bus runtime runs unchanged on the io_context, the nodes answer after a configurable
// latency, and the test can take the link down, power nodes off or inject error frames. Every
// frame on the "wire" is logged in candump text.
#pragma once

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <deque>
#include <functional>
#include <set>

#include "drivers/transport/can_frame.hpp"
#include "drivers/transport/socketcan_transport.hpp"
#include "network.hpp"

namespace fieldgate::test {

namespace simco = fieldgate::sim::canopen;

class SimChannel final : public CanChannel {
 public:
  struct Shared {
    std::vector<std::string> wire;  // every frame, in order, as candump text
    bool down = false;              // the interface is down: open fails, I/O errors
    std::chrono::microseconds latency{std::chrono::milliseconds(2)};
  };

  SimChannel(asio::any_io_executor ex, std::shared_ptr<Shared> shared, std::string nodes,
             simco::NodeConfig node_config = {})
      : shared_(std::move(shared)),
        timer_(ex),
        network_(node_config, [this](const simco::CanFrame& f) { from_nodes(f); }) {
    const auto now = simco::Clock::now();
    for (const auto id : simco::parse_node_ids(nodes)) network_.add_node(id, now);
  }

  // Called with each frame the bus sends, before and after the nodes received it: a test can
  // power a node off or on at that point of the exchange.
  std::function<void(const CanFrame&)> before_delivery, after_delivery;

  simco::Network& network() { return network_; }
  std::string execute(const std::string& line) {
    return network_.execute(line, simco::Clock::now()).message;
  }
  // An error frame from the controller (delivered to the bus only, as on a real interface).
  void inject_error(CanFrame error) {
    error.error = true;
    pending_.push_back({simco::Clock::now(), error});
    timer_.cancel();
  }

  std::error_code open(const std::vector<uint32_t>& cob_ids) override {
    if (shared_->down) return std::make_error_code(std::errc::network_down);
    filter_ = {cob_ids.begin(), cob_ids.end()};
    open_ = true;
    return {};
  }
  void close() override {
    open_ = false;
    timer_.cancel();
  }
  bool is_open() const override { return open_; }

  asio::awaitable<std::error_code> receive(std::vector<CanFrame>& frames) override {
    for (;;) {
      if (!open_) co_return std::make_error_code(std::errc::bad_file_descriptor);
      if (shared_->down) co_return std::make_error_code(std::errc::network_down);
      const auto now = simco::Clock::now();
      network_.advance(now);
      while (!pending_.empty() && pending_.front().first <= now) {
        const auto f = pending_.front().second;
        pending_.pop_front();
        if (!f.error) shared_->wire.push_back(to_string(f));  // as the bus sees it
        if (f.error || filter_.count(f.id)) {
          frames.push_back(f);
          if (!f.error) ++stats_.frames_received;
        }
      }
      if (!frames.empty()) co_return std::error_code{};
      auto next = std::min(network_.next_deadline(), now + std::chrono::milliseconds(20));
      if (!pending_.empty()) next = std::min(next, pending_.front().first);
      timer_.expires_at(next);
      co_await timer_.async_wait(asio::as_tuple(asio::use_awaitable));
    }
  }

  asio::awaitable<std::error_code> send(const CanFrame& frame, std::chrono::microseconds) override {
    if (!open_) co_return std::make_error_code(std::errc::bad_file_descriptor);
    if (shared_->down) co_return std::make_error_code(std::errc::network_down);
    ++stats_.frames_sent;
    shared_->wire.push_back(to_string(frame));
    if (before_delivery) before_delivery(frame);
    network_.receive(to_sim(frame), simco::Clock::now());
    if (after_delivery) after_delivery(frame);
    co_return std::error_code{};
  }

  // A frame (candump text) another tool on the bus sends to the nodes, e.g. an SDO request; the
  // nodes' answers reach the bus like any frame of theirs.
  bool from_other_tool(const std::string& candump) {
    const auto frame = simco::parse_frame(candump);
    if (!frame) return false;
    shared_->wire.push_back(candump);
    network_.receive(*frame, simco::Clock::now());
    return true;
  }

  std::string describe() const override { return "simulated CAN"; }
  const CanChannelStats& stats() const override { return stats_; }

 private:
  static simco::CanFrame to_sim(const CanFrame& frame) {
    simco::CanFrame f;
    f.id = frame.id;
    f.len = frame.len;
    f.rtr = frame.rtr;
    f.data = frame.data;
    return f;
  }

  void from_nodes(const simco::CanFrame& f) {
    CanFrame frame;
    frame.id = f.id;
    frame.len = f.len;
    frame.rtr = f.rtr;
    frame.data = f.data;
    if (shared_->down) return;  // lost, as on a real bus
    pending_.push_back({simco::Clock::now() + shared_->latency, frame});
    timer_.cancel();
  }

  std::shared_ptr<Shared> shared_;
  asio::steady_timer timer_;
  simco::Network network_;
  std::deque<std::pair<simco::TimePoint, CanFrame>> pending_;
  std::set<uint32_t> filter_;
  bool open_ = false;
  CanChannelStats stats_;
};

}  // namespace fieldgate::test
