// Issue 49: serve nothing stale as fresh. A polled point whose last polls all failed, or whose
// value is older than its bound, is stale: point_is_fresh says so at literal times, the register
// map answers it 0x0B while the node's other points keep serving, a good poll restores it, and
// the failed polls are logged at most once a minute per node. The serial bus counts a point's
// failed polls (garbled replies here) on a time source the test sets.
#include <gtest/gtest.h>

#include <boost/asio/io_context.hpp>

#include <string>
#include <vector>

#include "control_table_test.hpp"
#include "copley_requests.hpp"
#include "fake_line.hpp"
#include "gateway/bus/poll_failure_report.hpp"
#include "gateway/bus/serial_bus.hpp"
#include "gateway/image/point_freshness.hpp"
#include "gateway/register_map/register_map_handler.hpp"
#include "serial_bus_files.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using modbus::ExceptionCode;

const SteadyTime kT0 = SteadyTime{} + 100h;

// position and velocity polled fast (100 ms), temperature slow (1 s), target write-only.
Model motor_model() {
  Model m;
  m.name = "motor";
  m.poll_classes = {{"fast", 100ms}, {"slow", 1s}};
  const auto point = [&](const std::string& name, const std::string& poll_class, bool read) {
    PointDef p;
    p.name = name;
    p.poll_class = poll_class;
    if (read) p.read = ReadSpec{};
    m.points.push_back(p);
  };
  point("position", "fast", true);
  point("velocity", "fast", true);
  point("temperature", "slow", true);
  point("target", "", false);
  return m;
}
constexpr std::size_t kPosition = 0, kVelocity = 1, kTemperature = 2, kTarget = 3;

NodeImage image_of(const Model& m) {
  NodeImage node;
  node.points.assign(m.points.size(), {});
  for (auto& p : node.points) p = {1, kT0, true};
  return node;
}

void fail_poll(PointValue& p) {
  ++p.failed_polls;
  ++p.failed_polls_total;
}

TEST(PointFreshness, FailedPollsInARowMakeOnlyThatPointStaleAndAGoodPollRestoresIt) {
  const Model m = motor_model();
  NodeImage node = image_of(m);  // default policy: 3 failed polls, 4 periods, at least 2 s
  for (int i = 0; i < 2; ++i) fail_poll(node.points[kVelocity]);
  EXPECT_TRUE(point_is_fresh(node, m, kVelocity, kT0));
  fail_poll(node.points[kVelocity]);
  EXPECT_FALSE(point_is_fresh(node, m, kVelocity, kT0)) << "3 failed polls in a row";
  EXPECT_TRUE(point_is_fresh(node, m, kPosition, kT0)) << "the same node's other point";

  store_polled_value(node.points[kVelocity], 42, kT0 + 100ms);
  EXPECT_TRUE(point_is_fresh(node, m, kVelocity, kT0 + 100ms));
  EXPECT_EQ(node.points[kVelocity].value, 42);
  EXPECT_EQ(node.points[kVelocity].failed_polls, 0u);
  EXPECT_EQ(node.points[kVelocity].failed_polls_total, 3u) << "kept across a good value";

  node.freshness.failed_polls = 0;  // failures alone never make a point stale
  for (int i = 0; i < 10; ++i) fail_poll(node.points[kVelocity]);
  EXPECT_TRUE(point_is_fresh(node, m, kVelocity, kT0 + 100ms));
}

TEST(PointFreshness, AValueOlderThanItsBoundIsStale) {
  const Model m = motor_model();
  NodeImage node = image_of(m);
  // fast: 4 x 100 ms is below the 2 s floor; slow: 4 x 1 s.
  EXPECT_EQ(point_age_bound(node, m, kPosition), 2s);
  EXPECT_EQ(point_age_bound(node, m, kTemperature), 4s);
  EXPECT_TRUE(point_is_fresh(node, m, kPosition, kT0 + 2s));
  EXPECT_FALSE(point_is_fresh(node, m, kPosition, kT0 + 2s + 1us));
  EXPECT_TRUE(point_is_fresh(node, m, kTemperature, kT0 + 4s));
  EXPECT_FALSE(point_is_fresh(node, m, kTemperature, kT0 + 4s + 1us));

  // The node's own poll periods (poll: overrides) count, not the model's.
  node.freshness.poll_periods = {1s, 1s, 10s, 0us};
  EXPECT_EQ(point_age_bound(node, m, kPosition), 4s);
  EXPECT_TRUE(point_is_fresh(node, m, kTemperature, kT0 + 40s));
  EXPECT_FALSE(point_is_fresh(node, m, kTemperature, kT0 + 41s));

  node.freshness.periods = 0;  // no age bound
  EXPECT_TRUE(point_is_fresh(node, m, kTemperature, kT0 + 1000h));
}

TEST(PointFreshness, APointThatIsNotPolledIsFreshOnceItHasAValue) {
  const Model m = motor_model();
  NodeImage node = image_of(m);
  EXPECT_TRUE(point_is_fresh(node, m, kTarget, kT0 + 1000h)) << "write-only";
  // Polled no longer (e.g. a CANopen object the device lacks, read once): its value stays.
  node.polled = {true, true, false, false};
  EXPECT_TRUE(point_is_fresh(node, m, kTemperature, kT0 + 1000h));
  EXPECT_FALSE(point_is_fresh(node, m, kPosition, kT0 + 1000h));
  node.points[kTarget].valid = false;
  EXPECT_FALSE(point_is_fresh(node, m, kTarget, kT0)) << "never read nor written";
  EXPECT_FALSE(point_is_fresh(node, m, 99, kT0)) << "no such point";
}

TEST(PointFreshness, AHeldLineKeepsTheLastValuesServed) {
  // A capital-letter move holds the line: nothing is polled until its handshake.
  const Model m = motor_model();
  NodeImage node = image_of(m);
  node.action.holding_line = true;
  EXPECT_TRUE(point_is_fresh(node, m, kPosition, kT0 + 60s));
  node.action.holding_line = false;
  EXPECT_FALSE(point_is_fresh(node, m, kPosition, kT0 + 60s));
}

TEST(PollFailureReport, OneLinePerNodeAMinuteWithTheCountsAndThePoints) {
  const Model m = motor_model();
  NodeImage node = image_of(m);
  PollFailureReport report;
  EXPECT_FALSE(report.due("b", "n", node, m, kT0)) << "nothing failed";

  fail_poll(node.points[kVelocity]);
  report.failed({static_cast<int>(kVelocity)}, "garbled: 'ok' where a value was expected");
  auto line = report.due("b", "n", node, m, kT0);
  ASSERT_TRUE(line) << "the first failure is told at once";
  EXPECT_EQ(line->level, log::Level::notice);
  EXPECT_EQ(line->text,
            "bus b node n: 1 failed poll(s) (last: garbled: 'ok' where a value was expected): "
            "velocity 1 in a row, 1 in all");

  for (int i = 0; i < 3; ++i) {
    fail_poll(node.points[kVelocity]);
    report.failed({static_cast<int>(kVelocity)}, "garbled: 'ok' where a value was expected");
    EXPECT_FALSE(report.due("b", "n", node, m, kT0 + 10s * (i + 1)));
  }
  fail_poll(node.points[kTemperature]);
  report.failed({static_cast<int>(kTemperature)}, "timeout: no reply");
  EXPECT_FALSE(report.due("b", "n", node, m, kT0 + 59s));
  line = report.due("b", "n", node, m, kT0 + 60s);
  ASSERT_TRUE(line);
  EXPECT_EQ(line->level, log::Level::warning) << "velocity is stale";
  EXPECT_EQ(line->text,
            "bus b node n: 4 failed poll(s) in the last 60 s (last: timeout: no reply): velocity 4 "
            "in a row, 4 in all (stale: answered 0x0B); temperature 1 in a row, 1 in all");
  EXPECT_FALSE(report.due("b", "n", node, m, kT0 + 200s)) << "nothing failed since";
  report.failed({static_cast<int>(kPosition)}, "timeout: no reply");
  EXPECT_TRUE(report.due("b", "n", node, m, kT0 + 200s));
}

// The register map over the Techno table of the control tests (node state online).
class RegisterMapFreshness : public test::ControlTableTest {
 protected:
  void start(const std::string& modbus_section = "") {
    start_control(modbus_section);
    if (HasFatalFailure()) return;
    handler_ = std::make_unique<RegisterMapHandler>(config_, 0, image_, *actions_, *control_);
    image_.node(0).state = NodeState::online;
    const auto now = std::chrono::steady_clock::now();
    for (auto& p : image_.node(0).points) p = {7, now, true};
  }
  const RegisterEntry& input(const std::string& name) const {
    for (const auto& e :
         config_->register_map.unit(1)->tables[static_cast<std::size_t>(Table::input_registers)])
      if (e.name == name) return e;
    ADD_FAILURE() << "no input register " << name;
    static const RegisterEntry none;
    return none;
  }
  PointValue& point(const std::string& name) {
    return image_.node(0).points[static_cast<std::size_t>(input(name).index)];
  }
  // The exception of reading the named point, or nullopt when served.
  std::optional<ExceptionCode> read(const std::string& name) {
    const auto& e = input(name);
    const auto result =
        handler_->read_registers(1, modbus::RegisterTable::input_registers, e.address, e.count);
    if (result.ok()) return std::nullopt;
    return result.exception();
  }

  std::unique_ptr<RegisterMapHandler> handler_;
};

TEST_F(RegisterMapFreshness, FailedPollsAnswer0x0BWhileTheNodesOtherPointsServe) {
  start();
  EXPECT_EQ(read("position_x"), std::nullopt);
  point("position_x").failed_polls = 3;
  EXPECT_EQ(read("position_x"), ExceptionCode::gateway_target_failed);
  EXPECT_EQ(read("position_y"), std::nullopt);
  store_polled_value(point("position_x"), 5, std::chrono::steady_clock::now());
  EXPECT_EQ(read("position_x"), std::nullopt) << "a good poll restores it";
}

TEST_F(RegisterMapFreshness, AValueOlderThanItsBoundAnswers0x0B) {
  start();
  point("position_x").updated = std::chrono::steady_clock::now() - 1h;
  EXPECT_EQ(read("position_x"), ExceptionCode::gateway_target_failed);
  EXPECT_EQ(read("position_y"), std::nullopt);
  // Values carried over a reload are served while still within their bound, not after.
  image_.node(0).state = NodeState::starting;
  image_.node(0).carried_over = true;
  EXPECT_EQ(read("position_x"), ExceptionCode::gateway_target_failed);
  EXPECT_EQ(read("position_y"), std::nullopt);
}

TEST_F(RegisterMapFreshness, OfflineReadsLastValueStillServesAnOfflineNodesLastValues) {
  start("modbus:\n  offline_reads: last_value\n");
  point("position_x").updated = std::chrono::steady_clock::now() - 1h;
  EXPECT_EQ(read("position_x"), ExceptionCode::gateway_target_failed) << "online: stale";
  image_.node(0).state = NodeState::offline;  // the node's state says its values are old
  EXPECT_EQ(read("position_x"), std::nullopt);
}

TEST_F(RegisterMapFreshness, TheBoundIsConfiguredPerBus) {
  std::optional<LoadedConfig> loaded;
  EXPECT_EQ(load("buses:\n  - name: b\n    protocol: techno-c\n"
                 "    serial: {device: /dev/null, baud: 9600}\n"
                 "    timing: {stale_after: {failed_polls: 5, periods: 10, at_least: 30s}}\n"
                 "    nodes:\n"
                 "      - {name: table, address: 0, model: techno-c142, unit_id: 1}\n",
                 &loaded),
            "");
  ASSERT_TRUE(loaded);
  const NodeConfig& node = loaded->gateway.buses[0].nodes[0];
  const auto image = make_node_image(node);
  EXPECT_EQ(image->freshness.failed_polls, 5u);
  EXPECT_EQ(image->freshness.periods, 10u);
  EXPECT_EQ(image->freshness.at_least, 30s);
  EXPECT_EQ(image->freshness.poll_periods.size(), node.model->points.size());
}

TEST_F(RegisterMapFreshness, AWrongBoundIsReportedAtItsKey) {
  const auto loaded = [&](const std::string& stale_after) {
    return load(
        "buses:\n  - name: b\n    protocol: techno-c\n"
        "    serial: {device: /dev/null, baud: 9600}\n"
        "    timing: {stale_after: " +
        stale_after +
        "}\n    nodes:\n"
        "      - {name: table, address: 0, model: techno-c142, unit_id: 1}\n");
  };
  EXPECT_NE(loaded("{failed_polls: 1001}")
                .find("error: bus b timing stale_after failed_polls: 1001 is out of range 0..1000"),
            std::string::npos);
  EXPECT_NE(loaded("{at_least: -1s}").find("error: bus b timing stale_after at_least"),
            std::string::npos);
  EXPECT_NE(loaded("{age: 3s}").find("error: bus b timing stale_after"), std::string::npos);
  EXPECT_NE(loaded("3").find("error: bus b timing stale_after"), std::string::npos);
}

// The serial bus on an in-memory Copley line, on the test's time: velocity's replies turn into
// `ok` (garbled: a value was expected) while position's stay good.
class SerialBusFreshness : public ::testing::Test {
 protected:
  void SetUp() override {
    files_.write_model("1s", "  velocity: {type: int32, read: g r0x18, poll: fast}\n");
    config_ = files_.load(
        "    timing: {reply_timeout: 100ms, retries: 0, offline_after: 3, probe_interval: 5s,\n"
        "             stale_after: {failed_polls: 2, periods: 4, at_least: 2s}}\n",
        "      - {name: gw, address: 0, model: position, unit_id: 1}\n");
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
      std::string reply = "e 3";
      if (command == "g r0x32") reply = "v 1000";
      if (command == "g r0x18") reply = garble_ ? "ok" : "v " + std::to_string(++velocity_);
      if (command == "g f0x32") reply = "e 15";  // the proof of alignment after a garbled reply
      if (command == "g r0x90") reply = "v 115200";
      line_->deliver(reply + "\r");
    }
  }
  bool run_until(const std::function<bool()>& done) {
    const auto deadline = std::chrono::steady_clock::now() + 3s;
    while (!done() && std::chrono::steady_clock::now() < deadline) io_.run_for(1ms);
    return done();
  }
  const NodeImage& image() const { return *bus_->node_images().at(0); }
  const Model& model() const { return *config_->gateway.buses[0].nodes[0].model; }
  std::size_t index(const std::string& point) const {
    return static_cast<std::size_t>(model().find_point(point) - model().points.data());
  }
  const PointValue& point(const std::string& name) const { return image().points[index(name)]; }
  bool fresh(const std::string& name) const {
    return point_is_fresh(image(), model(), index(name), now_);
  }
  // Moves the bus's time on by one period and waits until both points were polled at it.
  bool next_round() {
    const auto seen = [this] {
      return point("position").updated == now_ &&
             (point("velocity").updated == now_ ||
              point("velocity").failed_polls_total > velocity_failures_);
    };
    velocity_failures_ = point("velocity").failed_polls_total;
    now_ += 1s;
    bus_->recheck();
    return run_until(seen);
  }

  test::SerialBusFiles files_{"freshness"};
  asio::io_context io_;
  SteadyTime now_ = kT0;
  std::shared_ptr<const LoadedConfig> config_;
  test::FakeLine* line_ = nullptr;
  test::CopleyRequests requests_;
  bool garble_ = false;
  int velocity_ = 0;
  uint64_t velocity_failures_ = 0;
  std::shared_ptr<SerialBus> bus_;
};

TEST_F(SerialBusFreshness, AGarbledPointGoesStaleAfterItsFailedPollsTheOtherKeepsServing) {
  // position is polled at the start, velocity half a period later (PollPlan staggers them).
  ASSERT_TRUE(run_until([&] { return point("position").valid; }));
  ASSERT_TRUE(next_round());
  EXPECT_TRUE(fresh("velocity"));
  garble_ = true;
  ASSERT_TRUE(next_round());
  EXPECT_EQ(point("velocity").failed_polls, 1u);
  EXPECT_TRUE(fresh("velocity")) << "1 of 2 failed polls";
  ASSERT_TRUE(next_round());
  EXPECT_EQ(point("velocity").failed_polls, 2u);
  EXPECT_FALSE(fresh("velocity"));
  EXPECT_TRUE(fresh("position"));
  EXPECT_EQ(point("position").failed_polls_total, 0u);
  EXPECT_EQ(image().counters.failed_polls, 2u);
  EXPECT_EQ(image().state, NodeState::online);

  garble_ = false;
  ASSERT_TRUE(next_round());
  EXPECT_TRUE(fresh("velocity")) << "a good poll restores it";
  EXPECT_EQ(point("velocity").failed_polls, 0u);
  EXPECT_EQ(point("velocity").failed_polls_total, 2u);
  // Older than 4 periods of 1 s: stale, at literal times.
  EXPECT_TRUE(point_is_fresh(image(), model(), index("position"), now_ + 4s));
  EXPECT_FALSE(point_is_fresh(image(), model(), index("position"), now_ + 4s + 1us));
}

}  // namespace
}  // namespace fieldgate
