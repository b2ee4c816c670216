// Issue 30: a serial bus sends the next poll's request the moment the reply before it has been
// accepted (Link::send_ahead), before its bookkeeping. On an in-memory line whose far end is a
// Copley gateway amplifier with nodes 3 and 5 behind it, answering each request in order: polls
// go ahead, every value is the node's own, a command waiting goes before the poll that would
// have gone ahead, and a family whose request sent ahead is not the one its exchange sends
// costs a proof of alignment, never a value.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include <iostream>
#include <map>
#include <memory>
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

const std::map<std::string, int64_t> kPositions = {{"", 1000}, {"3 ", 3333}, {"5 ", 5555}};
constexpr int64_t kNotAPosition = 777;  // what the amplifier answers to g r0x33

// The Copley family, with pipelined_request() saying g r0x33 for every `lie_every`-th poll that
// it is asked about: a family whose request sent ahead differs from what its exchange sends.
class MisforeseeingFamily final : public ProtocolFamily {
 public:
  explicit MisforeseeingFamily(int lie_every)
      : copley_(std::dynamic_pointer_cast<ProtocolFamily>(make_family("copley-ascii"))),
        lie_every_(lie_every) {}
  int lies = 0;

  std::string_view name() const override { return copley_->name(); }
  std::optional<NodeAddress> parse_address(std::string_view text,
                                           std::string& error) const override {
    return copley_->parse_address(text, error);
  }
  NodeContextPtr bind_node(const NodeAddress& node, const Model& model) override {
    return copley_->bind_node(node, model);
  }
  asio::awaitable<void> on_link_open(Link& link, const LinkTiming& timing) override {
    co_await copley_->on_link_open(link, timing);
  }
  asio::awaitable<Reply> transact_node(Link& link, NodeContext& node, const Request& request,
                                       const LinkTiming& timing) override {
    co_return co_await copley_->transact_node(link, node, request, timing);
  }
  std::optional<std::string> pipelined_request(NodeContext& node, const Request& request) override {
    auto bytes = copley_->pipelined_request(node, request);
    if (bytes && ++asked_ % lie_every_ == 0) {
      ++lies;
      bytes->replace(bytes->find("r0x32"), 5, "r0x33");
    }
    return bytes;
  }
  asio::awaitable<LinkResync> resync_after_failure(Link& link, const LinkTiming& timing) override {
    co_return co_await copley_->resync_after_failure(link, timing);
  }
  std::optional<AlignmentProof> alignment_proof(NodeContext& node,
                                                const LinkTiming& timing) override {
    return copley_->alignment_proof(node, timing);
  }

 private:
  std::shared_ptr<ProtocolFamily> copley_;
  int lie_every_;
  int asked_ = 0;
};

class SerialBusSendAhead : public ::testing::Test {
 protected:
  void start(int lie_every = 0) {
    files_.write_model("1ms");
    auto loaded = files_.load(
        "    timing: {reply_timeout: 200ms, byte_timeout: 20ms, retries: 1, offline_after: 3}\n",
        "      - {name: gw, address: 0, model: position, unit_id: 1}\n"
        "      - {name: n3, address: 3, model: position, unit_id: 2}\n"
        "      - {name: n5, address: 5, model: position, unit_id: 3}\n");
    ASSERT_TRUE(loaded);
    if (lie_every > 0) {
      auto changed = std::make_shared<LoadedConfig>(*loaded);
      family_ = std::make_shared<MisforeseeingFamily>(lie_every);
      changed->gateway.buses[0].family = family_;
      loaded = changed;
    }
    config_ = loaded;
    auto line = test::fake_serial_line(io_);
    line_ = line.get();
    line_->keep_order();
    line_->set_far_end([this](std::string_view bytes) { on_write(bytes); });
    bus_ = test::run_serial_bus(io_, config_, std::move(line), [this](int node) { check(node); });
    ::testing::internal::CaptureStderr();
  }
  void TearDown() override {
    if (!bus_) return;
    bus_->stop();
    io_.run_for(50ms);
    log_ = ::testing::internal::GetCapturedStderr();
    if (HasFailure()) std::cerr << "--- bus log ---\n" << log_;
  }

  // Every request is answered in order, 500 us after it came (a few characters' wire time), and
  // journalled: three nodes polled every millisecond keep the line busy.
  void on_write(std::string_view bytes) {
    for (const auto& [request, prefix, command] : requests_.take(bytes)) {
      journal_.push_back(request);
      std::string reply = "e 3";
      if (command == "g r0x32" && kPositions.count(prefix))
        reply = "v " + std::to_string(kPositions.at(prefix));
      if (command == "g r0x33") reply = "v " + std::to_string(kNotAPosition);
      if (command == "g r0x90" && prefix.empty()) reply = "v 115200";
      if (command == "g f0x32") reply = "e 15";  // the proof of alignment's answer
      if (command.rfind("s r0xca ", 0) == 0) reply = "ok";
      line_->deliver(reply + "\r", 500us);
    }
  }

  const NodeImage& image(int node) { return *bus_->node_images().at(static_cast<size_t>(node)); }
  // After every poll: each node's position is its own.
  void check(int node) {
    const auto& v = image(node).points[0];
    if (!v.valid) return;
    const int64_t expected = node == 0 ? 1000 : node == 1 ? 3333 : 5555;
    if (v.value != expected && wrong_++ == 0)
      first_wrong_ = "node " + std::to_string(node) + " served " + std::to_string(v.value);
    ++good_;
  }
  bool run_until(const std::function<bool()>& done, std::chrono::milliseconds limit = 5s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (!done() && std::chrono::steady_clock::now() < deadline) io_.run_for(1ms);
    return done();
  }

  test::SerialBusFiles files_{"send-ahead"};
  asio::io_context io_;
  std::shared_ptr<const LoadedConfig> config_;
  std::shared_ptr<MisforeseeingFamily> family_;
  FakeLine* line_ = nullptr;
  test::CopleyRequests requests_;
  std::vector<std::string> journal_;
  std::shared_ptr<SerialBus> bus_;
  int wrong_ = 0, good_ = 0;
  std::string first_wrong_, log_;
};

TEST_F(SerialBusSendAhead, PollsGoAheadAndEveryValueIsTheNodesOwn) {
  ASSERT_NO_FATAL_FAILURE(start());
  ASSERT_TRUE(run_until([&] { return good_ >= 300; })) << good_ << " polls";
  EXPECT_EQ(wrong_, 0) << first_wrong_;
  // The line is saturated (1 ms periods): after the first exchanges nearly every poll goes out
  // the moment the reply before it is taken.
  EXPECT_GT(line_->writes_ahead(), good_ / 2) << good_ << " polls";
  EXPECT_EQ(bus_->counters().sent_ahead, static_cast<uint64_t>(line_->writes_ahead()));
  EXPECT_EQ(bus_->counters().sent_ahead_lost, 0u);
  EXPECT_EQ(bus_->counters().alignment_proofs, 0u);
  EXPECT_EQ(bus_->counters().resyncs, 0u);
  for (const auto& request : journal_) EXPECT_EQ(request.find("r0x33"), std::string::npos);
}

TEST_F(SerialBusSendAhead, ACommandWaitingGoesBeforeThePollThatWouldHaveGoneAhead) {
  ASSERT_NO_FATAL_FAILURE(start());
  ASSERT_TRUE(run_until([&] { return line_->writes_ahead() >= 20; }));
  for (int i = 1; i <= 20; ++i) {
    // Queued while a poll (sent ahead or not) is on the line: the command is the next request.
    std::size_t on_the_line = 0;
    std::optional<Reply> reply;
    asio::co_spawn(
        io_,
        [&, i]() -> asio::awaitable<void> {
          Request write{"s r0xca " + std::to_string(i), Request::Expect::ack};
          on_the_line = journal_.size();
          reply = co_await bus_->submit(0, std::move(write));
        },
        asio::detached);
    ASSERT_TRUE(run_until([&] { return reply.has_value(); }));
    EXPECT_EQ(reply->status, Reply::Status::ok);
    ASSERT_GT(journal_.size(), on_the_line);
    EXPECT_EQ(journal_[on_the_line], "s r0xca " + std::to_string(i))
        << "write " << i << " went out behind " << journal_[on_the_line];
    io_.run_for(std::chrono::milliseconds(1 + i % 3));
  }
  EXPECT_EQ(wrong_, 0) << first_wrong_;
}

TEST_F(SerialBusSendAhead, ARequestSentAheadThatIsNotTheExchangesOwnCostsAProofNotAValue) {
  ASSERT_NO_FATAL_FAILURE(start(7));
  ASSERT_TRUE(run_until([&] { return family_->lies >= 10 && good_ >= 200; }))
      << family_->lies << " requests misforeseen, " << good_ << " polls";
  EXPECT_EQ(wrong_, 0) << first_wrong_;
  int sent_wrong = 0;
  for (const auto& request : journal_) sent_wrong += request.find("r0x33") != std::string::npos;
  EXPECT_GT(sent_wrong, 0) << "the wrong requests went ahead";
  EXPECT_GE(bus_->counters().alignment_proofs, 1u);
  EXPECT_GE(bus_->counters().sent_ahead_lost, static_cast<uint64_t>(sent_wrong));
  EXPECT_FALSE(bus_->node_images().empty());
  for (int node = 0; node < 3; ++node) EXPECT_EQ(image(node).state, NodeState::online);
  io_.run_for(1ms);
  log_ = ::testing::internal::GetCapturedStderr();
  ::testing::internal::CaptureStderr();
  EXPECT_NE(log_.find("was sent ahead, but the exchange sent other bytes"), std::string::npos)
      << log_;
}

}  // namespace
}  // namespace fieldgate
