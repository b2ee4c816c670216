// Issue 31, item 3: a reload that changes only a serial bus's nodes is applied to those nodes
// (SerialBus::reconfigure). The bus runs on an in-memory line whose far end is a Copley gateway
// amplifier with nodes 3 and 5 behind it, each answering its own position; the link stays open,
// the nodes it already ran keep their state, images and commands, and new nodes are polled.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include <cctype>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "fake_line.hpp"
#include "gateway/bus/serial_bus.hpp"
#include "gateway/config/config_loader.hpp"
#include "serial_bus_files.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using test::FakeLine;

const std::map<std::string, int64_t> kPositions = {{"", 1000}, {"3 ", 3333}, {"5 ", 5555}};
constexpr auto kReplyDelay = 20ms;

class SerialBusReconfigure : public ::testing::Test {
 protected:
  void SetUp() override {
    files_.write_model("20ms", "setpoints:\n  speed: {type: int32, default: 10}\n");
    auto line = test::fake_serial_line(io_);
    line_ = line.get();
    line_->keep_order();
    line_->set_far_end([this](std::string_view bytes) { on_write(bytes); });
    config_ = load(kTiming,
                   "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
                   "      - {name: n3, address: 3, model: position, unit_id: 2}\n");
    ASSERT_TRUE(config_);
    bus_ = test::run_serial_bus(io_, config_, std::move(line));
  }
  void TearDown() override {
    if (bus_) bus_->stop();
    io_.run_for(50ms);
  }

  static constexpr const char* kTiming =
      "    timing: {reply_timeout: 100ms, retries: 0, offline_after: 2, probe_interval: 200ms}\n";

  std::shared_ptr<const LoadedConfig> load(const std::string& timing, const std::string& nodes) {
    return files_.load(timing, nodes);
  }

  bool reconfigure(const std::shared_ptr<const LoadedConfig>& next) {
    return bus_->reconfigure(next, next->gateway.buses[0], 0, nullptr);
  }

  void on_write(std::string_view bytes) {
    pending_ += bytes;
    for (auto cr = pending_.find('\r'); cr != std::string::npos; cr = pending_.find('\r')) {
      std::string request = pending_.substr(0, cr);
      pending_.erase(0, cr + 1);
      std::string prefix;
      if (request.size() > 2 && std::isdigit(static_cast<unsigned char>(request[0])) &&
          request[1] == ' ') {
        prefix = request.substr(0, 2);
        request.erase(0, 2);
      }
      journal_.push_back(prefix + request);
      std::string reply = "e 3";
      if (request == "g r0x32" && kPositions.count(prefix))
        reply = "v " + std::to_string(kPositions.at(prefix));
      else if (request == "g r0x32")
        reply = "e 32";
      else if (request == "g r0x90")
        reply = "v 115200";
      else if (request.rfind("s r0xca ", 0) == 0)
        reply = "ok";
      line_->deliver(reply + "\r", kReplyDelay);
    }
  }

  const NodeImage& image(int node) { return *bus_->node_images().at(static_cast<size_t>(node)); }

  bool run_until(const std::function<bool()>& done, std::chrono::milliseconds limit = 3s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (!done() && std::chrono::steady_clock::now() < deadline) io_.run_for(2ms);
    return done();
  }

  bool serves(int node, int64_t value) {
    const auto& v = image(node).points[0];
    return image(node).state == NodeState::online && v.valid && v.value == value;
  }

  test::SerialBusFiles files_{"reconfigure"};
  asio::io_context io_;
  std::shared_ptr<const LoadedConfig> config_;
  FakeLine* line_ = nullptr;
  std::string pending_;
  std::vector<std::string> journal_;
  std::shared_ptr<SerialBus> bus_;
};

TEST_F(SerialBusReconfigure, ANodeAddedAheadOfTheOthersIsPolledWhileTheOthersCarryOn) {
  ASSERT_TRUE(run_until([&] { return serves(0, 1000) && serves(1, 3333); }));
  const auto gw = bus_->node_images().at(0);
  const auto n3 = bus_->node_images().at(1);
  const auto reconnects = bus_->counters().reconnects;
  const auto transactions = n3->counters.transactions;

  auto next = load(kTiming,
                   "      - {name: n5, address: 5, model: position, unit_id: 3}\n"
                   "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
                   "      - {name: n3, address: 3, model: position, unit_id: 2,"
                   " poll: {fast: 40ms}}\n");
  ASSERT_TRUE(reconfigure(next));
  EXPECT_EQ(bus_->config().nodes.size(), 3u);
  EXPECT_EQ(bus_->node_images().at(1), gw) << "gw keeps its image, at its new place";
  EXPECT_EQ(bus_->node_images().at(2), n3);
  EXPECT_EQ(n3->state, NodeState::online) << "n3 stays online: nothing about it was restarted";
  EXPECT_EQ(bus_->node_config(2).name, "n3");
  EXPECT_EQ(bus_->number_of(*n3), 2);

  ASSERT_TRUE(run_until([&] { return serves(0, 5555); })) << "the new node is polled";
  EXPECT_TRUE(run_until([&] { return n3->counters.transactions > transactions + 2; }))
      << "and the others still are";
  EXPECT_TRUE(serves(1, 1000));
  EXPECT_TRUE(serves(2, 3333));
  EXPECT_EQ(bus_->counters().reconnects, reconnects) << "the link was not reopened";
}

TEST_F(SerialBusReconfigure, ACommandQueuedAcrossTheReloadGoesToItsOwnNode) {
  ASSERT_TRUE(run_until([&] { return serves(0, 1000) && serves(1, 3333); }));
  // Right after a poll went out: its reply is kReplyDelay away, so the command waits in the queue.
  const auto written = journal_.size();
  ASSERT_TRUE(run_until([&] { return journal_.size() > written; }));
  std::optional<Reply> reply;
  asio::co_spawn(
      io_,
      [&]() -> asio::awaitable<void> {
        Request request{"s r0xca 42", Request::Expect::ack};
        CommandOptions options;
        reply = co_await bus_->submit(1, request, options);  // n3, local 1 before the reload
      },
      asio::detached);
  io_.run_for(1ms);
  ASSERT_FALSE(reply) << "the command must still be queued when the reload comes";

  ASSERT_TRUE(reconfigure(load(kTiming,
                               "      - {name: n5, address: 5, model: position, unit_id: 3}\n"
                               "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
                               "      - {name: n3, address: 3, model: position, unit_id: 2}\n")));
  ASSERT_TRUE(run_until([&] { return reply.has_value(); }));
  EXPECT_EQ(reply->status, Reply::Status::ok) << reply->text;
  EXPECT_NE(std::find(journal_.begin(), journal_.end(), "3 s r0xca 42"), journal_.end())
      << "sent to n3, now the bus's third node";
  EXPECT_EQ(std::find(journal_.begin(), journal_.end(), "s r0xca 42"), journal_.end())
      << "not to gw, the bus's second node now";
}

TEST_F(SerialBusReconfigure, SetpointsTheSiteChangedTakeTheirNewValuesAndOthersKeepThePlcs) {
  ASSERT_TRUE(run_until([&] { return serves(1, 3333); }));
  auto images = bus_->node_images();
  images[0]->setpoints.at(0) = 77;  // written by the PLC
  images[1]->setpoints.at(0) = 78;
  ASSERT_TRUE(reconfigure(load(kTiming,
                               "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
                               "      - {name: n3, address: 3, model: position,"
                               " unit_id: 2, setpoints: {speed: 5}}\n")));
  EXPECT_EQ(images[0]->setpoints.at(0), 77);
  EXPECT_EQ(images[1]->setpoints.at(0), 5);
}

TEST_F(SerialBusReconfigure, ABusWhoseLinkOrNodesAsDevicesChangedIsNotChangedInPlace) {
  ASSERT_TRUE(run_until([&] { return serves(1, 3333); }));
  const auto images = bus_->node_images();
  // n3 taken away: the family would keep it bound.
  EXPECT_FALSE(
      reconfigure(load(kTiming, "      - {name: gw, address: 0, model: position, unit_id: 1}\n")));
  // n3 at another address: another device under the same name.
  EXPECT_FALSE(reconfigure(load(kTiming,
                                "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
                                "      - {name: n3, address: 5, model: position, unit_id: 2}\n")));
  // The bus's timing: the link itself changes.
  EXPECT_FALSE(reconfigure(load("    timing: {reply_timeout: 150ms}\n",
                                "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
                                "      - {name: n3, address: 3, model: position, unit_id: 2}\n")));
  EXPECT_EQ(bus_->node_images(), images) << "nothing changed by a refused reconfigure";
  EXPECT_EQ(bus_->config().nodes.size(), 2u);
  EXPECT_TRUE(run_until([&] { return serves(0, 1000) && serves(1, 3333); }));
}

}  // namespace
}  // namespace fieldgate
