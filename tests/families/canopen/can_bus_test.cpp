// The CAN bus runtime on the io_context against the simulator's CiA 301/402 nodes on an
// in-memory channel (sim_channel.hpp): overlap across nodes, one SDO per node, heartbeat
// consumer, EMCY, TPDOs without SDO traffic, aborts, commands, link loss. Real time, short
// timeouts; the same paths run on a kernel vcan in the vcan tests.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include <filesystem>
#include <fstream>
#include <regex>

#include "gateway/can_bus.hpp"
#include "gateway/config_loader.hpp"
#include "sim_channel.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using test::SimChannel;
namespace fs = std::filesystem;

constexpr const char* kTiming =
    "reply_timeout: 50ms, retries: 1, offline_after: 2, probe_interval: 100ms, "
    "heartbeat_timeout: 300ms, start_nodes: true, reconnect_min: 50ms, reconnect_max: 200ms";

class CanBusTest : public ::testing::Test {
 protected:
  void TearDown() override {
    if (bus_) {
      bus_->stop();
      io_.run_for(100ms);
    }
    fs::remove_all(dir_);
  }

  void start(const std::string& sim_nodes, const std::string& nodes_yaml,
             const std::string& timing = kTiming, int heartbeat_ms = 50) {
    dir_ = fs::temp_directory_path() /
           ("fieldgate-canbus-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    std::ofstream(dir_ / "gw.yaml") << "models: " FIELDGATE_SOURCE_DIR "/config/models\n"
                                    << "buses:\n  - name: can\n    protocol: canopen\n"
                                    << "    can: {interface: vcan0}\n"
                                    << "    timing: {" << timing << "}\n"
                                    << "    nodes:\n"
                                    << nodes_yaml;
    Diagnostics d;
    auto loaded = load_gateway_config((dir_ / "gw.yaml").string(), d);
    ASSERT_TRUE(loaded) << d.to_text();
    config_ = std::make_shared<LoadedConfig>(std::move(*loaded));
    sim::canopen::NodeConfig nc;
    nc.heartbeat_ms = static_cast<uint16_t>(heartbeat_ms);
    auto channel = std::make_unique<SimChannel>(io_.get_executor(), wire_, sim_nodes, nc);
    sim_ = channel.get();
    bus_ = std::make_shared<CanBus>(
        io_.get_executor(), config_, config_->gateway.buses[0], 0, [this](int) { ++updates_; },
        std::move(channel));
    asio::co_spawn(
        io_, [bus = bus_]() -> asio::awaitable<void> { co_await bus->run(); }, asio::detached);
  }

  bool run_until(const std::function<bool()>& pred, std::chrono::milliseconds limit = 3s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      if (pred()) return true;
      io_.run_for(2ms);
    }
    return pred();
  }

  Reply submit(int node, const std::string& command, CommandOptions options = {},
               bool bus_wide = false) {
    std::optional<Reply> reply;
    asio::co_spawn(
        io_,
        [&]() -> asio::awaitable<void> {
          Request r{command, Request::Expect::ack, NumberFormat::decimal, bus_wide};
          reply = co_await bus_->submit(node, r, options);
        },
        asio::detached);
    run_until([&] { return reply.has_value(); }, 10s);
    if (!reply) return Reply{Reply::Status::timeout, {}, 0, "test: no reply"};
    return *reply;
  }

  const NodeImage& image(int node) { return *bus_->node_images().at(static_cast<size_t>(node)); }
  std::optional<int64_t> point(int node, const std::string& name) {
    const auto& model = *config_->gateway.buses[0].nodes.at(static_cast<size_t>(node)).model;
    for (std::size_t i = 0; i < model.points.size(); ++i)
      if (model.points[i].name == name) {
        const auto& v = image(node).points[i];
        if (!v.valid) return std::nullopt;
        return v.value;
      }
    ADD_FAILURE() << "no point " << name;
    return std::nullopt;
  }
  bool online(int node) { return image(node).state == NodeState::online; }
  bool offline(int node) { return image(node).state == NodeState::offline; }
  std::size_t wire_count(const std::string& pattern, std::size_t from = 0) {
    const std::regex re(pattern);
    std::size_t n = 0;
    for (std::size_t i = from; i < wire_->wire.size(); ++i)
      n += std::regex_match(wire_->wire[i], re) ? 1 : 0;
    return n;
  }
  std::string wire_text() {
    std::string s;
    for (const auto& f : wire_->wire) s += f + "\n";
    return s;
  }

  asio::io_context io_;
  fs::path dir_;
  std::shared_ptr<const LoadedConfig> config_;
  std::shared_ptr<SimChannel::Shared> wire_ = std::make_shared<SimChannel::Shared>();
  SimChannel* sim_ = nullptr;
  std::shared_ptr<CanBus> bus_;
  int updates_ = 0;
};

const std::string kTwoDrives =
    "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n"
    "      - {name: axis3, address: 3, model: canopen-cia402, unit_id: 2}\n";

TEST_F(CanBusTest, StartsNodesAndTakesPdosWithoutSdo) {
  start("2,3", kTwoDrives);
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5 && point(1, "nmt_state") == 5; }))
      << wire_text();
  EXPECT_GE(wire_count("000#0102"), 1u);
  EXPECT_GE(wire_count("000#0103"), 1u);
  ASSERT_TRUE(run_until([&] { return point(0, "statusword") && point(0, "position_actual"); }));
  EXPECT_EQ(*point(0, "statusword") & 0x4F, 0x40);  // switch on disabled
  const auto pdos = bus_->node_status(0).pdos;
  run_until([] { return false; }, 400ms);
  EXPECT_GT(bus_->node_status(0).pdos, pdos);
  // Statusword and position came from TPDO1 only: never an SDO upload of 0x6041 or 0x6064.
  EXPECT_EQ(wire_count("60[23]#4041600000000000"), 0u) << wire_text();
  EXPECT_EQ(wire_count("60[23]#4064600000000000"), 0u) << wire_text();
  EXPECT_GT(wire_count("602#40.*"), 0u);  // other points are polled
  EXPECT_TRUE(online(0) && online(1));
  EXPECT_GT(bus_->counters().frames_received, 0u);
  EXPECT_EQ(bus_->counters().reconnects, 1u);
}

TEST_F(CanBusTest, TransfersOverlapAcrossNodesOnePerNode) {
  wire_->latency = 5ms;
  start("2,3,4",
        "      - {name: a, address: 2, model: canopen-cia402, unit_id: 1, poll: {fast: 5ms}}\n"
        "      - {name: b, address: 3, model: canopen-cia402, unit_id: 2, poll: {fast: 5ms}}\n"
        "      - {name: c, address: 4, model: canopen-cia402, unit_id: 3, poll: {fast: 5ms}}\n");
  run_until([] { return false; }, 600ms);
  ASSERT_GT(bus_->counters().transactions, 30u);
  // Per node, requests and responses alternate: never a second request before the answer.
  bool overlap = false;
  std::map<int, int> outstanding;
  for (const auto& f : wire_->wire) {
    const unsigned id = std::stoul(f.substr(0, 3), nullptr, 16);
    if (id > 0x600 && id < 0x680) {
      const int node = static_cast<int>(id - 0x600);
      EXPECT_EQ(outstanding[node], 0) << "second request to node " << node << " at " << f;
      outstanding[node] = 1;
      int busy = 0;
      for (const auto& [n, o] : outstanding) busy += o;
      if (busy > 1) overlap = true;
    } else if (id > 0x580 && id < 0x600) {
      outstanding[static_cast<int>(id - 0x580)] = 0;
    }
  }
  EXPECT_TRUE(overlap) << "no two nodes had transfers in flight at the same time";
  EXPECT_EQ(bus_->counters().timeouts, 0u);
}

TEST_F(CanBusTest, AbortIsADeviceErrorWithItsCode) {
  start("2,3", kTwoDrives);
  ASSERT_TRUE(run_until([&] { return online(0); }));
  auto r = submit(0, "write modes_of_operation 3");  // the simulator has pp and hm only
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, 0x06090030);
  EXPECT_NE(r.text.find("invalid value for parameter"), std::string::npos) << r.text;
  EXPECT_EQ(point(0, "sdo_abort_code"), 0x06090030);
  EXPECT_EQ(image(0).counters.last_device_error, 0x06090030);
  EXPECT_TRUE(online(0));  // an abort is an answer
  r = submit(0, "read 0x1234:0 UNSIGNED8");
  EXPECT_EQ(r.device_code, 0x06020000);
  EXPECT_NE(r.text.find("object does not exist"), std::string::npos) << r.text;
  r = submit(0, "write controlword 70000");  // rendered out of range: refused, not sent
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, 0x06090030);
  EXPECT_NE(r.text.find("not sent"), std::string::npos) << r.text;
}

TEST_F(CanBusTest, SegmentedBothDirections) {
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n");
  ASSERT_TRUE(run_until([&] { return online(0); }));
  auto r = submit(0, "read 0x1008:0 VISIBLE_STRING");
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(r.text, "fieldgate sim CiA 402 drive");
  const std::string label = "conveyor left, axis two (segmented)";
  r = submit(0, "write 0x2000:0 VISIBLE_STRING \"" + label + "\"");
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  r = submit(0, "read 0x2000:0 VISIBLE_STRING");
  EXPECT_EQ(r.text, label);
  EXPECT_GE(wire_count("602#2100200023000000"), 1u) << wire_text();  // 35 bytes announced
}

TEST_F(CanBusTest, ModelStepsEnableAndMove) {
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n");
  // Switch On Disabled once the drive has initialised (statusword 0x0000 before).
  ASSERT_TRUE(
      run_until([&] { return online(0) && (point(0, "statusword").value_or(0) & 0x4F) == 0x40; }));
  const Model& model = *config_->gateway.buses[0].nodes[0].model;
  const auto run_action = [&](const std::string& name, std::map<std::string, int64_t> values) {
    const ActionDef* a = model.find_action(name);
    EXPECT_TRUE(a) << name;
    if (!a) return false;
    for (const auto& step : a->steps) {
      const auto text = step.command.render([&](std::string_view k) {
        const auto it = values.find(std::string(k));
        return it == values.end() ? int64_t{0} : it->second;
      });
      const auto r = submit(0, text, {step.accept_no_reply, step.urgent});
      if (r.status != Reply::Status::ok) {
        ADD_FAILURE() << name << ": '" << text << "': " << r.text << "\n" << wire_text();
        return false;
      }
    }
    return true;
  };
  ASSERT_TRUE(run_action("enable", {}));
  ASSERT_TRUE(run_until([&] { return (point(0, "statusword").value_or(0) & 0x6F) == 0x27; }));
  ASSERT_TRUE(run_action(
      "move_absolute",
      {{"target", 3000}, {"velocity", 20000}, {"acceleration", 100000}, {"deceleration", 100000}}));
  ASSERT_TRUE(run_until(
      [&] {
        return point(0, "position_actual") == 3000 && (point(0, "statusword").value_or(0) & 0x0400);
      },
      5s))
      << "position " << point(0, "position_actual").value_or(-1);
  ASSERT_TRUE(run_action("move_relative", {{"distance", -500},
                                           {"velocity", 20000},
                                           {"acceleration", 100000},
                                           {"deceleration", 100000}}));
  EXPECT_TRUE(run_until([&] { return point(0, "position_actual") == 2500; }, 5s));
  ASSERT_TRUE(run_action("disable", {}));
}

TEST_F(CanBusTest, WaitStepFailsWithTheObservedValue) {
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n");
  ASSERT_TRUE(run_until([&] { return online(0) && point(0, "statusword"); }));
  const auto r = submit(0, "wait statusword & 0x6F == 0x27 within 100ms");
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code & 0x4F, 0x40);  // switch on disabled
  EXPECT_NE(r.text.find("waited 100 ms for & 0x6F == 0x27"), std::string::npos) << r.text;
}

TEST_F(CanBusTest, UrgentCommandInterruptsAWait) {
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n");
  ASSERT_TRUE(run_until([&] { return online(0); }));
  std::optional<Reply> waited;
  asio::co_spawn(
      io_,
      [&]() -> asio::awaitable<void> {
        const Request wait{"wait statusword == 0x1234 within 5s"};
        waited = co_await bus_->submit(0, wait);
      },
      asio::detached);
  run_until([] { return false; }, 100ms);
  const auto r = submit(0, "write controlword 0x02", {false, true});
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  ASSERT_TRUE(run_until([&] { return waited.has_value(); }, 1s));
  EXPECT_EQ(waited->status, Reply::Status::device_error);
  EXPECT_NE(waited->text.find("interrupted by an urgent command"), std::string::npos);
  // NMT as urgent goes out at once.
  EXPECT_EQ(submit(0, "nmt start", {false, true}).status, Reply::Status::ok);
}

TEST_F(CanBusTest, HeartbeatLossAndReturn) {
  // SDO timeouts would take the node offline later than its missing heartbeat.
  start("2,3", kTwoDrives,
        "reply_timeout: 50ms, retries: 1, offline_after: 10, probe_interval: 100ms, "
        "heartbeat_timeout: 150ms, start_nodes: true");
  ASSERT_TRUE(run_until([&] { return online(0) && online(1) && point(1, "nmt_state") == 5; }));
  sim_->execute("power-off 3");
  ASSERT_TRUE(run_until([&] { return offline(1); }, 2s));
  EXPECT_TRUE(online(0));
  EXPECT_LT(image(1).counters.consecutive_timeouts, 10u);  // the heartbeat, not SDO timeouts
  auto r = submit(1, "write controlword 6");
  EXPECT_EQ(r.status, Reply::Status::unreachable);
  EXPECT_EQ(r.text, "node is offline");
  const auto from = wire_->wire.size();
  sim_->execute("power-on 3");
  ASSERT_TRUE(run_until([&] { return online(1); }, 2s));
  EXPECT_TRUE(run_until([&] { return wire_count("000#0103", from) >= 1; }))
      << "no NMT start after boot-up";
  EXPECT_TRUE(run_until([&] { return point(1, "nmt_state") == 5; }));
  EXPECT_GE(wire_count("703#00", from), 1u);
}

TEST_F(CanBusTest, EmergencyReachesDiagnostics) {
  start("2,3", kTwoDrives);
  ASSERT_TRUE(run_until([&] { return online(0) && point(0, "statusword"); }));
  sim_->execute("fault 2 0x2310");
  ASSERT_TRUE(run_until([&] { return point(0, "emcy_code") == 0x2310; }));
  EXPECT_EQ(point(0, "emcy_error_register"), 0x03);
  EXPECT_EQ(image(0).counters.last_device_error, 0x2310);
  EXPECT_NE(image(0).counters.last_error_text.find("current, device output side"),
            std::string::npos);
  EXPECT_TRUE(run_until([&] { return (point(0, "statusword").value_or(0) & 0x08) != 0; }));
  EXPECT_EQ(point(1, "emcy_code"), 0);
  // Fault reset: the error reset EMCY clears the point, the diagnostic keeps the last code.
  for (const char* step : {"write controlword 0x00", "write controlword 0x80",
                           "wait statusword & 0x4F == 0x40 within 1s"})
    EXPECT_EQ(submit(0, step).status, Reply::Status::ok) << step;
  EXPECT_TRUE(run_until([&] { return point(0, "emcy_code") == 0; }));
  EXPECT_EQ(image(0).counters.last_device_error, 0x2310);
}

TEST_F(CanBusTest, SdoTimeoutsWithoutHeartbeatConsumer) {
  start("2,3", kTwoDrives,
        "reply_timeout: 30ms, retries: 0, offline_after: 2, probe_interval: 100ms");
  ASSERT_TRUE(run_until([&] { return online(0) && online(1); }));
  const auto from = wire_->wire.size();
  sim_->execute("power-off 3");
  ASSERT_TRUE(run_until([&] { return offline(1); }, 3s));
  EXPECT_GE(wire_count("603#80.{6}00000405", from), 2u) << wire_text();  // abort 0x05040000
  EXPECT_TRUE(online(0));
  EXPECT_GE(image(1).counters.timeouts, 2u);
  sim_->execute("power-on 3");
  ASSERT_TRUE(run_until([&] { return online(1); }, 3s));
  EXPECT_GE(wire_count("603#4000100000000000", from), 1u);  // probed with 0x1000
}

TEST_F(CanBusTest, LinkDownAndBack) {
  start("2,3", kTwoDrives);
  ASSERT_TRUE(run_until([&] { return online(0) && online(1); }));
  wire_->down = true;
  ASSERT_TRUE(run_until([&] { return offline(0) && offline(1); }, 2s));
  EXPECT_FALSE(bus_->counters().link_up);
  auto r = submit(0, "write controlword 6");
  EXPECT_EQ(r.status, Reply::Status::unreachable);
  EXPECT_EQ(r.text, "bus link is down");
  run_until([] { return false; }, 300ms);  // several failed reopens
  wire_->down = false;
  ASSERT_TRUE(run_until([&] { return online(0) && online(1); }, 3s));
  EXPECT_TRUE(bus_->counters().link_up);
  EXPECT_EQ(bus_->counters().reconnects, 2u);
  EXPECT_EQ(submit(0, "write controlword 6").status, Reply::Status::ok);
}

TEST_F(CanBusTest, ErrorFramesAreCounted) {
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n");
  ASSERT_TRUE(run_until([&] { return online(0); }));
  sim_->inject_error(*canopen::parse_frame("20000004#0030000000000000"));
  sim_->inject_error(*canopen::parse_frame("20000040#0000000000000000"));
  ASSERT_TRUE(run_until([&] { return bus_->counters().error_frames == 2; }));
  EXPECT_EQ(bus_->counters().bus_off, 1u);
  EXPECT_TRUE(bus_->counters().link_up);
}

TEST_F(CanBusTest, BusWideNmtReachesEveryNode) {
  start("2,3", kTwoDrives);
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5 && point(1, "nmt_state") == 5; }));
  EXPECT_EQ(submit(0, "nmt pre-operational", {}, true).status, Reply::Status::ok);
  EXPECT_GE(wire_count("000#8000"), 1u);
  EXPECT_TRUE(
      run_until([&] { return point(0, "nmt_state") == 127 && point(1, "nmt_state") == 127; }));
}

}  // namespace
}  // namespace fieldgate
