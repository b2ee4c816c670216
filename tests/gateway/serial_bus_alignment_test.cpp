// Issue 26, item 1 and 2: replies carry no tag, and silence is no proof that a line is in step.
// The serial bus on an in-memory line whose far end is a Copley gateway amplifier that answers
// every request, in order, one at a time: an absent CAN node's e 32 comes after the amplifier's
// CAN timeout (130 ms, beyond the 50 ms reply timeout and the guard after it), and the amplifier
// may pause for 230 ms (a busy CPU, a USB adapter's buffer). Each node's position is distinct and
// constant, so a reply booked against the wrong request shows; every write is journalled with its
// own reply. What is asserted does not depend on timing: whatever the delays, no value is served
// that the node did not send, no write is confirmed that its node did not answer `ok`, and no node
// that answers is counted unreachable because of another node's e 32.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include <iostream>
#include <map>
#include <optional>
#include <ostream>
#include <random>
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

// Bus-local node indexes and what each node's position reads.
constexpr int kGateway = 0, kNode3 = 1, kNode5 = 2, kNode7 = 3;
const std::map<std::string, int64_t> kPositions = {{"", 1000}, {"3 ", 3333}, {"5 ", 5555}};

// A Copley gateway amplifier with nodes 3 and 5 behind it on CAN and node 7 absent.
class CopleyLine {
 public:
  struct Executed {
    std::string request;
    std::string reply;
    long at_ms = 0, due_ms = 0;  // when heard and when answered, from the first request
  };
  CopleyLine(FakeLine& line, unsigned seed, bool pauses)
      : line_(line), random_(seed), pauses_(pauses) {
    line_.keep_order();  // one amplifier answers one request after another
  }

  void on_write(std::string_view bytes) {
    for (const auto& request : requests_.take(bytes)) answer(request);
  }
  const std::vector<Executed>& journal() const { return journal_; }
  long ms_now() const {
    return static_cast<long>(
        std::chrono::duration_cast<std::chrono::milliseconds>(FakeLine::Clock::now() - start_)
            .count());
  }

 private:
  void answer(const test::CopleyRequest& heard) {
    const std::string& request = heard.line;
    const std::string& prefix = heard.prefix;
    const std::string& command = heard.command;
    auto delay = std::chrono::milliseconds(1 + random_() % 3);
    if (pauses_ && ++count_ % 12 == 0) delay += 230ms;
    std::string reply;
    if (prefix == "7 ") {
      reply = "e 32";
      delay += 130ms;  // the amplifier's CAN timeout: past the reply timeout and the guard
    } else if (command == "g f0x32" && prefix.empty()) {
      reply = "e 15";
    } else if (command == "g r0x90" && prefix.empty()) {
      reply = "v 115200";
    } else if (command == "g r0x32") {
      reply = "v " + std::to_string(kPositions.at(prefix));
    } else if (command == "s r0x24 41") {
      reply = "e 14";
    } else if (command.rfind("s r0xca ", 0) == 0) {
      reply = "ok";
    } else {
      reply = "e 3";
    }
    // One request at a time: this one is handled once the one before it was answered.
    const auto now = FakeLine::Clock::now();
    const auto due = std::max(now, busy_until_) + delay;
    busy_until_ = due;
    if (journal_.empty()) start_ = now;
    const auto ms = [&](FakeLine::Clock::time_point t) {
      return static_cast<long>(
          std::chrono::duration_cast<std::chrono::milliseconds>(t - start_).count());
    };
    journal_.push_back({request, reply, ms(now), ms(due)});
    line_.deliver(reply + "\r", due - now);
  }

  FakeLine& line_;
  std::mt19937 random_;
  bool pauses_;
  int count_ = 0;
  test::CopleyRequests requests_;
  std::vector<Executed> journal_;
  FakeLine::Clock::time_point busy_until_{};
  FakeLine::Clock::time_point start_{};
};

struct Run {
  const char* name;
  bool pauses;
  unsigned seed;
};

// Without it GoogleTest prints the bytes, the pointer among them, into the ctest name.
void PrintTo(const Run& run, std::ostream* os) {
  *os << (run.pauses ? "pauses" : "late e 32") << ", seed " << run.seed;
}

class SerialBusAlignment : public ::testing::TestWithParam<Run> {
 protected:
  void SetUp() override {
    files_.write_model("20ms", "  desired_state: {type: int16, write: \"s r0x24 {value}\"}\n");
    config_ = files_.load(
        "    timing: {reply_timeout: 50ms, byte_timeout: 10ms, retries: 1, offline_after: 3,\n"
        "             probe_interval: 200ms}\n",
        "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
        "      - {name: n3, address: 3, model: position, unit_id: 2, reply_timeout: 50ms}\n"
        "      - {name: n5, address: 5, model: position, unit_id: 3, reply_timeout: 50ms}\n"
        "      - {name: n7, address: 7, model: position, unit_id: 4, reply_timeout: 50ms}\n");
    ASSERT_TRUE(config_);
    auto line = test::fake_serial_line(io_);
    line_ = line.get();
    far_end_.emplace(*line_, GetParam().seed, GetParam().pauses);
    line_->set_far_end([this](std::string_view bytes) { far_end_->on_write(bytes); });
    bus_ = test::run_serial_bus(io_, config_, std::move(line),
                                [this](int node) { check_values(node); });
    ::testing::internal::CaptureStderr();
  }
  void TearDown() override {
    if (!bus_) return;
    bus_->stop();
    io_.run_for(50ms);
    log_ = ::testing::internal::GetCapturedStderr();
    if (HasFailure()) {
      std::cerr << "--- bus log ---\n" << log_ << "--- far end (request -> reply) ---\n";
      for (const auto& e : far_end_->journal())
        std::cerr << e.at_ms << " " << e.request << " -> " << e.reply << " at " << e.due_ms << "\n";
    }
  }

  const NodeImage& image(int node) { return *bus_->node_images().at(static_cast<size_t>(node)); }

  // After every poll: each present node's position is its own.
  void check_values(int node) {
    const auto& v = image(node).points[0];
    if (!v.valid) return;
    const int64_t expected = node == kGateway ? 1000 : node == kNode3 ? 3333 : 5555;
    if (node == kNode7 || v.value != expected) {
      if (wrong_++ == 0)
        first_wrong_ = "node " + std::to_string(node) + " served " + std::to_string(v.value) +
                       " at " + std::to_string(far_end_->ms_now()) + " ms";
    }
    ++good_;
  }

  std::optional<Reply> submit(int node, const std::string& command) {
    std::optional<Reply> reply;
    asio::co_spawn(
        io_,
        [&]() -> asio::awaitable<void> {
          // Named, not temporaries: GCC 12 destroys temporaries of a co_await's call twice.
          Request request{command, Request::Expect::ack};
          CommandOptions options;
          reply = co_await bus_->submit(node, request, options);
        },
        asio::detached);
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (!reply && std::chrono::steady_clock::now() < deadline) io_.run_for(2ms);
    return reply;
  }

  test::SerialBusFiles files_{"alignment", GetParam().name};
  asio::io_context io_;
  std::shared_ptr<const LoadedConfig> config_;
  FakeLine* line_ = nullptr;
  std::optional<CopleyLine> far_end_;
  std::shared_ptr<SerialBus> bus_;
  int wrong_ = 0, good_ = 0;
  std::string first_wrong_, log_;
};

TEST_P(SerialBusAlignment, NoValueOrConfirmationComesFromAnotherExchange) {
  std::mt19937 random(GetParam().seed);
  struct Write {
    int node;
    std::string command;
    Reply reply;
  };
  std::vector<Write> writes;
  for (int i = 1; i <= 30; ++i) {
    io_.run_for(std::chrono::milliseconds(10 + random() % 40));
    const int node = static_cast<int>(random() % 4);
    const std::string command =
        random() % 3 == 0 ? std::string("s r0x24 41") : "s r0xca " + std::to_string(i * 10 + node);
    auto reply = submit(node, command);
    ASSERT_TRUE(reply) << "write " << i << " never answered";
    writes.push_back({node, command, *reply});
  }
  io_.run_for(300ms);

  EXPECT_EQ(wrong_, 0) << first_wrong_;
  EXPECT_GT(good_, 10);
  const std::vector<std::string> prefix = {"", "3 ", "5 ", "7 "};
  int confirmed = 0;
  for (const auto& w : writes) {
    if (w.reply.status != Reply::Status::ok) continue;
    ++confirmed;
    EXPECT_NE(w.command, "s r0x24 41") << "a write the device refuses was confirmed";
    EXPECT_NE(w.node, kNode7) << "a write to an absent node was confirmed";
    const auto& journal = far_end_->journal();
    const auto it =
        std::find_if(journal.begin(), journal.end(), [&](const CopleyLine::Executed& e) {
          return e.request == prefix[static_cast<size_t>(w.node)] + w.command;
        });
    ASSERT_NE(it, journal.end()) << w.command << " confirmed but never executed";
    EXPECT_EQ(it->reply, "ok");
  }
  EXPECT_GT(confirmed, 0);
  // A present node refuses with its own code, never with the absent node's e 32.
  for (const auto& w : writes) {
    if (w.node != kNode7 && w.reply.status == Reply::Status::device_error) {
      EXPECT_EQ(w.reply.device_code, 14) << w.command << " to node " << w.node;
    }
  }
  for (int node : {kGateway, kNode3, kNode5})
    EXPECT_EQ(image(node).counters.unreachable, 0u)
        << "node " << node << " booked another node's e 32";
  // Late replies came, and were drained (while the line went quiet, or during a proof).
  EXPECT_GT(bus_->counters().alignment_proofs, 0u);
  EXPECT_GT(bus_->counters().stray_replies + bus_->counters().resync_bytes, 0u);
  // Polls were sent ahead of the bookkeeping (Link::send_ahead) through all of it.
  EXPECT_GT(line_->writes_ahead(), 0);
}

INSTANTIATE_TEST_SUITE_P(Copley, SerialBusAlignment,
                         ::testing::Values(Run{"late_e32_seed1", false, 1},
                                           Run{"late_e32_seed2", false, 2},
                                           Run{"pauses_seed3", true, 3},
                                           Run{"pauses_seed4", true, 4}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate
