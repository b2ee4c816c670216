// Issue 27, item 5: the serial bus's scheduling on a time source the test sets. The bus runs on an
// in-memory line whose far end is a Copley gateway amplifier with node 3 behind it; time moves
// only when the test moves it, so what comes due when (polls, probes, reopening a dead line) is
// checked at literal times, and the order of polls and queued commands on the wire is exact.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include <algorithm>
#include <cctype>
#include <optional>
#include <string>
#include <vector>

#include "copley_requests.hpp"
#include "fake_line.hpp"
#include "gateway/bus/serial_bus.hpp"
#include "gateway/config/config_loader.hpp"
#include "serial_bus_files.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using test::FakeLine;

// gw (address 0) is polled first at the start, n3 half a period later (PollPlan staggers them).
constexpr std::chrono::milliseconds kPeriod = 1s;

class SerialBusSchedule : public ::testing::Test {
 protected:
  void SetUp() override {
    files_.write_model("1s");
    config_ = files_.load(
        // reply_timeout runs on the real clock (the far end answers at once): 200 ms, so a loaded
        // host cannot time out a reply and take a node offline under the test.
        "    timing: {reply_timeout: 200ms, retries: 0, offline_after: 1, probe_interval: 5s}\n",
        "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
        "      - {name: n3, address: 3, model: position, unit_id: 2}\n");
    ASSERT_TRUE(config_);
    auto line = test::fake_serial_line(io_);
    line_ = line.get();
    line_->keep_order();
    line_->set_far_end([this](std::string_view bytes) { on_write(bytes); });
    bus_ = test::run_serial_bus(io_, config_, std::move(line), nullptr, [this] { return now_; });
  }
  void TearDown() override {
    if (bus_) bus_->stop();
    io_.run_for(50ms);
  }

  void on_write(std::string_view bytes) {
    for (const auto& [request, prefix, command] : requests_.take(bytes)) {
      journal_.push_back(request);
      if (silent_) continue;
      const bool to_n3 = prefix == "3 ";
      std::string reply = "e 3";
      if (command == "g r0x32") reply = to_n3 ? "v 3333" : "v 1000";
      if (command.rfind("s r0xca ", 0) == 0) reply = "ok";
      line_->deliver(reply + "\r");
    }
  }

  // Moves the bus's time on and lets it decide again.
  void advance(std::chrono::microseconds by) {
    now_ += by;
    bus_->recheck();
  }
  // Runs the bus for `d` of real time (its own time stands still meanwhile).
  void run_for(std::chrono::milliseconds d) { io_.run_for(d); }
  bool run_until(const std::function<bool()>& done, std::chrono::milliseconds limit = 3s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (!done() && std::chrono::steady_clock::now() < deadline) io_.run_for(1ms);
    return done();
  }
  std::size_t count(const std::string& request) const {
    return static_cast<std::size_t>(std::count(journal_.begin(), journal_.end(), request));
  }
  // Queues `n` writes to gw (s r0xca 1..n), to start when the bus is next run (before a
  // recheck() made after this), and counts their replies.
  void queue_writes(int n) {
    for (int i = 1; i <= n; ++i)
      asio::co_spawn(
          io_,
          [this, i]() -> asio::awaitable<void> {
            Request write{"s r0xca " + std::to_string(i), Request::Expect::ack};
            const Reply r = co_await bus_->submit(0, std::move(write));
            if (r.status == Reply::Status::ok) ++answered_;
          },
          asio::detached);
  }
  std::string journal_text() const {
    std::string text;
    for (const auto& r : journal_) text += "'" + r + "' ";
    return text + "; n3 " + std::string(to_string(image_of(1).state));
  }
  const NodeImage& image_of(int node) const {
    return *bus_->node_images().at(static_cast<size_t>(node));
  }
  const NodeImage& image(int node) { return *bus_->node_images().at(static_cast<size_t>(node)); }

  test::SerialBusFiles files_{"schedule"};
  asio::io_context io_;
  SteadyTime now_ = SteadyTime{} + 100h;
  std::shared_ptr<const LoadedConfig> config_;
  FakeLine* line_ = nullptr;
  bool silent_ = false;
  test::CopleyRequests requests_;
  std::vector<std::string> journal_;
  int answered_ = 0;
  std::shared_ptr<SerialBus> bus_;
};

TEST_F(SerialBusSchedule, PollsComeDueOnTheBusesTimeNotTheWallClock) {
  ASSERT_TRUE(run_until([&] { return count("g r0x32") == 1; }));
  // More than a period of real time, none of the bus's own: nothing more comes due.
  run_for(kPeriod + 200ms);
  EXPECT_EQ(count("g r0x32"), 1u);
  EXPECT_EQ(count("3 g r0x32"), 0u);

  advance(kPeriod / 2 - 1ms);
  run_for(50ms);
  EXPECT_EQ(count("3 g r0x32"), 0u) << "1 ms early";
  advance(1ms);
  ASSERT_TRUE(run_until([&] { return count("3 g r0x32") == 1; })) << journal_text();
  advance(kPeriod / 2);
  ASSERT_TRUE(run_until([&] { return count("g r0x32") == 2; }));
  run_for(50ms);
  EXPECT_EQ(journal_, (std::vector<std::string>{"g r0x32", "3 g r0x32", "g r0x32"}));
}

TEST_F(SerialBusSchedule, APollOnTimeWaitsForOneCommandALatePollGoesFirst) {
  ASSERT_TRUE(run_until([&] { return count("g r0x32") == 1; }));
  // n3's poll comes due exactly now, with four writes queued: one write, the poll, the rest.
  queue_writes(4);
  advance(kPeriod / 2);
  ASSERT_TRUE(run_until([&] { return answered_ == 4; }));
  EXPECT_EQ(journal_, (std::vector<std::string>{"g r0x32", "s r0xca 1", "3 g r0x32", "s r0xca 2",
                                                "s r0xca 3", "s r0xca 4"}));

  // Both polls late by more than a tenth of their period, and the four writes above spent the
  // credit that lets a command go ahead of late polls: the polls go first.
  journal_.clear();
  answered_ = 0;
  queue_writes(3);
  advance(kPeriod + 200ms);  // gw 700 ms late, n3 200 ms
  ASSERT_TRUE(run_until([&] { return answered_ == 3; }));
  EXPECT_EQ(journal_, (std::vector<std::string>{"g r0x32", "3 g r0x32", "s r0xca 1", "s r0xca 2",
                                                "s r0xca 3"}));
}

TEST_F(SerialBusSchedule, AnOccasionalWriteGoesAheadOfLatePolls) {
  ASSERT_TRUE(run_until([&] { return count("g r0x32") == 1; }));
  advance(kPeriod / 2);
  ASSERT_TRUE(run_until([&] { return count("3 g r0x32") == 1; }));
  // Both polls late, as on a saturated line; no command for a while, so the credit is whole: the
  // write waits for nothing but the line.
  journal_.clear();
  queue_writes(1);
  advance(kPeriod + 200ms);
  ASSERT_TRUE(run_until([&] { return answered_ == 1 && journal_.size() == 3; })) << journal_text();
  EXPECT_EQ(journal_, (std::vector<std::string>{"s r0xca 1", "g r0x32", "3 g r0x32"}));
}

TEST_F(SerialBusSchedule, ALineWhereNothingAnswersIsReopenedOneProbeIntervalAfterItFellSilent) {
  silent_ = true;
  ASSERT_TRUE(run_until([&] { return image(0).state == NodeState::offline; }));
  advance(kPeriod / 2);
  ASSERT_TRUE(run_until([&] { return image(1).state == NodeState::offline; }));
  const auto sent = journal_.size();
  run_for(300ms);  // real time passes, the bus's does not: no probe, no reopen
  EXPECT_EQ(line_->opens(), 0);
  EXPECT_EQ(journal_.size(), sent);

  // gw went offline at the start: its probe (the first) is due 5 s later.
  advance(5s - kPeriod / 2 - 1ms);
  run_for(50ms);
  EXPECT_EQ(line_->opens(), 0) << "1 ms before the probe interval is up";
  advance(1ms);
  ASSERT_TRUE(run_until([&] { return line_->opens() == 1; }))
      << "nothing answers on the whole line: it is reopened so the link-open procedure runs again";
  run_for(100ms);
  EXPECT_EQ(line_->opens(), 1) << "and not again until another probe interval has passed";
}

}  // namespace
}  // namespace fieldgate
