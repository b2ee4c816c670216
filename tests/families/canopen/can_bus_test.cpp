// The CAN bus runtime on the io_context against the simulator's CiA 301/402 nodes on an
// in-memory channel (sim_channel.hpp): overlap across nodes, one SDO per node, heartbeat
// consumer, EMCY, TPDOs without SDO traffic, aborts, commands, link loss. Real time, short
// timeouts; the same paths run on a kernel vcan in the vcan tests. The simulated nodes power up
// as CiA 301 devices ship: 0x1017 = 0, no heartbeat until the bus configures it.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include <filesystem>
#include <fstream>
#include <regex>

#include "compiled_request.hpp"
#include "gateway/bus/can_bus.hpp"
#include "gateway/config/config_loader.hpp"
#include "sim_channel.hpp"
#include "tests/harness/text_checks.hpp"

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
    if (capturing_) ::testing::internal::GetCapturedStderr();
    fs::remove_all(dir_);
  }

  // Nodes power up as they ship: 0x1017 = 0, no heartbeat until the bus sets it.
  static sim::canopen::NodeConfig as_shipped() {
    sim::canopen::NodeConfig nc;
    nc.heartbeat_ms = 0;
    return nc;
  }

  void start(const std::string& sim_nodes, const std::string& nodes_yaml,
             const std::string& timing = kTiming, sim::canopen::NodeConfig nc = as_shipped()) {
    dir_ = fs::temp_directory_path() /
           ("fieldgate-canbus-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    config_ = load("gw.yaml", nodes_yaml, timing);
    ASSERT_TRUE(config_);
    auto channel = std::make_unique<SimChannel>(io_.get_executor(), wire_, sim_nodes, nc);
    sim_ = channel.get();
    bus_ = std::make_shared<CanBus>(
        io_.get_executor(), config_, config_->gateway.buses[0], 0, [this](int) { ++updates_; },
        std::move(channel));
    asio::co_spawn(
        io_, [bus = bus_]() -> asio::awaitable<void> { co_await bus->run(); }, asio::detached);
  }

  // A configuration of the bus `can` with these nodes, written to `file` in the test's folder.
  std::shared_ptr<const LoadedConfig> load(const std::string& file, const std::string& nodes_yaml,
                                           const std::string& timing = kTiming) {
    std::ofstream(dir_ / file) << "models: " FIELDGATE_SOURCE_DIR "/config/models\n"
                               << "buses:\n  - name: can\n    protocol: canopen\n"
                               << "    can: {interface: vcan0}\n"
                               << "    timing: {" << timing << "}\n"
                               << "    nodes:\n"
                               << nodes_yaml;
    Diagnostics d;
    auto loaded = load_gateway_config((dir_ / file).string(), d);
    EXPECT_TRUE(loaded) << d.to_text();
    if (!loaded) return nullptr;
    return std::make_shared<const LoadedConfig>(std::move(*loaded));
  }

  bool run_until(const std::function<bool()>& pred, std::chrono::milliseconds limit = 3s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      if (pred()) return true;
      io_.run_for(2ms);
    }
    return pred();
  }

  // `command` compiled against the node's model, as the gateway compiles a model's templates.
  Request request(int node, const std::string& command, std::vector<int64_t> arguments = {},
                  bool bus_wide = false) {
    const auto& model = *config_->gateway.buses[0].nodes.at(static_cast<size_t>(node)).model;
    return test::compiled_request(command, &model, std::move(arguments), bus_wide);
  }

  Reply submit(int node, const std::string& command, CommandOptions options = {},
               bool bus_wide = false) {
    return submit(node, request(node, command, {}, bus_wide), options);
  }

  Reply submit(int node, Request request, CommandOptions options = {}) {
    std::optional<Reply> reply;
    asio::co_spawn(
        io_,
        [&]() -> asio::awaitable<void> { reply = co_await bus_->submit(node, request, options); },
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
  // Runs the io_context for `span`; false as soon as the node is seen not online.
  bool stays_online(int node, std::chrono::milliseconds span) {
    bool left = false;
    run_until(
        [&] {
          left = left || !online(node);
          return false;
        },
        span);
    return !left && online(node);
  }
  bool offline(int node) { return image(node).state == NodeState::offline; }
  std::size_t wire_count(const std::string& pattern, std::size_t from = 0) {
    const std::regex re(pattern);
    std::size_t n = 0;
    for (std::size_t i = from; i < wire_->wire.size(); ++i)
      n += std::regex_match(wire_->wire[i], re) ? 1 : 0;
    return n;
  }
  // The bus's log lines (stderr) from now until captured_log().
  void capture_log() {
    ::testing::internal::CaptureStderr();
    capturing_ = true;
  }
  std::string captured_log() {
    capturing_ = false;
    return ::testing::internal::GetCapturedStderr();
  }
  // Position of the first frame matching pattern on the wire, or npos.
  std::size_t wire_find(const std::string& pattern) {
    const std::regex re(pattern);
    for (std::size_t i = 0; i < wire_->wire.size(); ++i)
      if (std::regex_match(wire_->wire[i], re)) return i;
    return std::string::npos;
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
  bool capturing_ = false;
};

const std::string kTwoDrives =
    "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n"
    "      - {name: axis3, address: 3, model: canopen-cia402, unit_id: 2}\n";

// The bus takes the frame shape of its family once, when it is built: a stream family on it is
// a precise error (the loader pairs `can:` with canopen, so only a hand-made config gets here).
TEST_F(CanBusTest, StreamFamilyIsRefusedWhenTheBusIsBuilt) {
  start("2,3", kTwoDrives);
  BusConfig copy = config_->gateway.buses[0];
  copy.family = make_family("copley-ascii");
  try {
    CanBus bus(io_.get_executor(), config_, copy, 0, {},
               std::make_unique<SimChannel>(io_.get_executor(), wire_, "2", as_shipped()));
    ADD_FAILURE() << "a CAN bus was built with a stream family";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "bus can: protocol copley-ascii runs on a byte stream, not on a CAN bus (can:)");
  }
}

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
  EXPECT_GT(bus_->can_counters()->frames_received, 0u);
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
  // The diagnostic block serves the whole code (its low half, 0, would read "no error").
  const ProcessImage diagnostics(bus_->node_images());
  const auto now = std::chrono::steady_clock::now();
  EXPECT_EQ(diagnostics.diagnostic(0, DiagnosticField::last_device_error_code, now), 0x06020000);
  EXPECT_EQ(diagnostics.diagnostic(0, DiagnosticField::last_device_error, now), 0xffff);
  const auto* code = config_->map_of(0).unit(1)->find(Table::input_registers, 1021);
  ASSERT_NE(code, nullptr);
  EXPECT_EQ(code->name, "diag.last_device_error_code");
  EXPECT_EQ(code->address, 1021);
  EXPECT_EQ(code->count, 2);
  // The fields before it keep their registers.
  EXPECT_EQ(config_->map_of(0).unit(1)->find(Table::input_registers, 1010)->name,
            "diag.last_device_error");
  EXPECT_EQ(config_->map_of(0).unit(1)->find(Table::input_registers, 1019)->name,
            "diag.unreachable");
  // A setpoint outside the object's type: refused, not sent.
  r = submit(0, request(0, "write controlword {value}", {70000}));
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
      // The model's own templates, compiled when the configuration loaded.
      const auto r =
          submit(0,
                 Request::of_template(step.command,
                                      [&](std::string_view k) {
                                        const auto it = values.find(std::string(k));
                                        return it == values.end() ? int64_t{0} : it->second;
                                      }),
                 {step.accept_no_reply, step.urgent, {}});
      if (r.status != Reply::Status::ok) {
        ADD_FAILURE() << name << ": '" << step.command.source() << "': " << r.text << "\n"
                      << wire_text();
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
        const Request wait = request(0, "wait statusword == 0x1234 within 5s");
        waited = co_await bus_->submit(0, wait);
      },
      asio::detached);
  run_until([] { return false; }, 100ms);
  const auto r = submit(0, "write controlword 0x02", {false, true, {}});
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  ASSERT_TRUE(run_until([&] { return waited.has_value(); }, 1s));
  EXPECT_EQ(waited->status, Reply::Status::device_error);
  EXPECT_NE(waited->text.find("interrupted by an urgent command"), std::string::npos);
  // NMT as urgent goes out at once.
  EXPECT_EQ(submit(0, "nmt start", {false, true, {}}).status, Reply::Status::ok);
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
  // Its 0x1017 is back at 0 after the power cycle: configured again before the start.
  const auto write = wire_count("603#2B17100032000000", from);
  EXPECT_GE(write, 1u) << wire_text();
  EXPECT_TRUE(stays_online(1, 600ms));
}

// Issue 49: a node that boots while a probe to it is on its way. Literal order: the probe goes
// out to the powered-off node (lost), the node powers on and sends its boot-up, the probe times
// out. Online by the boot-up, the node stays online: the probe was sent before the boot-up, so
// its timeout says nothing about the node now. offline_after: 1, so one counted timeout would
// take it offline.
TEST_F(CanBusTest, ProbeLostToABootUpDoesNotTakeTheNodeOffline) {
  start("2,3", kTwoDrives,
        "reply_timeout: 50ms, retries: 0, offline_after: 1, probe_interval: 100ms, "
        "heartbeat_timeout: 300ms, start_nodes: true");
  ASSERT_TRUE(run_until([&] { return online(1) && point(1, "nmt_state") == 5; }));
  sim_->execute("power-off 3");
  ASSERT_TRUE(run_until([&] { return offline(1); }, 2s));
  const auto resets = image(1).controller_resets;
  const std::string probe = "603#4000100000000000";
  std::size_t probe_at = std::string::npos;
  sim_->after_delivery = [&](const CanFrame& f) {
    if (probe_at != std::string::npos || to_string(f) != probe) return;
    probe_at = wire_->wire.size() - 1;
    sim_->execute("power-on 3");
  };
  ASSERT_TRUE(run_until([&] { return probe_at != std::string::npos; }, 2s)) << wire_text();
  ASSERT_TRUE(run_until([&] { return online(1); }, 1s)) << wire_text();
  // The probe's timeout came after the boot-up: the client aborted it (0x05040000).
  ASSERT_TRUE(run_until([&] { return wire_count("603#8000100000000405", probe_at) == 1; }, 1s))
      << wire_text();
  EXPECT_EQ(wire_count("703#00", probe_at), 1u);  // boot-up between the probe and its abort
  EXPECT_TRUE(stays_online(1, 1s)) << image(1).counters.last_error_text << "\n" << wire_text();
  EXPECT_EQ(image(1).controller_resets, resets + 1);
  EXPECT_EQ(image(1).counters.consecutive_timeouts, 0u);
  EXPECT_GE(image(1).counters.timeouts, 1u);  // counted, just not toward offline
  EXPECT_TRUE(run_until([&] { return point(1, "nmt_state") == 5; }));
}

// The same for a poll on its way while the node restarts (power cycle between the request and
// its answer): online all along, configured and started again after its boot-up.
TEST_F(CanBusTest, PollLostToARestartDoesNotTakeTheNodeOffline) {
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n",
        "reply_timeout: 50ms, retries: 0, offline_after: 1, probe_interval: 100ms, "
        "heartbeat_timeout: 300ms, start_nodes: true");
  ASSERT_TRUE(run_until([&] { return online(0) && point(0, "nmt_state") == 5; }));
  const auto resets = image(0).controller_resets;
  int stage = 0;  // 1: the request is on its way to the powered-off node; 2: it powered on
  std::size_t lost_at = 0;
  sim_->before_delivery = [&](const CanFrame& f) {
    if (stage != 0 || f.id != 0x602 || f.data[0] != 0x40) return;  // an upload request
    stage = 1;
    lost_at = wire_->wire.size() - 1;
    sim_->execute("power-off 2");
  };
  sim_->after_delivery = [&](const CanFrame&) {
    if (stage != 1) return;
    stage = 2;
    sim_->execute("power-on 2");
  };
  ASSERT_TRUE(run_until([&] { return stage == 2; }, 3s)) << wire_text();
  EXPECT_TRUE(stays_online(0, 1s)) << image(0).counters.last_error_text << "\n" << wire_text();
  EXPECT_EQ(wire_count("602#80.{6}00000405", lost_at), 1u) << wire_text();  // it timed out
  EXPECT_EQ(image(0).controller_resets, resets + 1);
  EXPECT_GE(wire_count("602#2B17100064000000", lost_at), 1u);  // configured again
  EXPECT_TRUE(run_until([&] { return point(0, "nmt_state") == 5; }));
}

// Every boot-up the bus sees is a controller reset on the node's image (an action running
// across one does not end done).
TEST_F(CanBusTest, BootUpCountsAControllerReset) {
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n");
  ASSERT_TRUE(run_until([&] { return online(0) && point(0, "nmt_state") == 5; }));
  const auto resets = image(0).controller_resets;
  EXPECT_EQ(submit(0, "nmt reset").status, Reply::Status::ok);
  ASSERT_TRUE(run_until([&] { return image(0).controller_resets == resets + 1; }, 1s))
      << wire_text();
  sim_->execute("power-off 2");
  sim_->execute("power-on 2");
  ASSERT_TRUE(run_until([&] { return image(0).controller_resets == resets + 2; }, 1s))
      << wire_text();
  EXPECT_TRUE(run_until([&] { return point(0, "nmt_state") == 5; }));
  EXPECT_EQ(image(0).controller_resets, resets + 2);
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
  sim_->inject_error(*parse_frame("20000004#0030000000000000"));
  sim_->inject_error(*parse_frame("20000040#0000000000000000"));
  ASSERT_TRUE(run_until([&] { return bus_->can_counters()->error_frames == 2; }));
  EXPECT_EQ(bus_->can_counters()->bus_off, 1u);
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

// --- devices as they ship: 0x1017 = 0 --------------------------------------------------------

const std::string kCia301Node =
    "      - {name: dev, address: 2, model: canopen-cia301, unit_id: 1}\n";
// Expedited download of 0x1017:0 = 100 ms (a third of the 300 ms consumer time).
const std::string kHeartbeatWrite = "602#2B17100064000000";

TEST_F(CanBusTest, ConfiguresTheHeartbeatProducerBeforeNmtStart) {
  start("2", kCia301Node);
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5; })) << wire_text();
  const auto write = wire_find(kHeartbeatWrite);
  const auto nmt_start = wire_find("000#0102");
  ASSERT_NE(write, std::string::npos) << wire_text();
  ASSERT_NE(nmt_start, std::string::npos) << wire_text();
  EXPECT_LT(write, nmt_start);
  EXPECT_GT(wire_find("702#(05|7F)"), wire_find("582#60171000.*")) << "heartbeat before the write";
  // Three consumer times and more: never offline, the heartbeat keeps it alive.
  EXPECT_TRUE(stays_online(0, 1500ms)) << image(0).counters.last_error_text;
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::heartbeat);
  EXPECT_GE(wire_count("702#05"), 10u);
  // The bus's own confirmed write is the point's value, before any poll of 0x1017.
  EXPECT_EQ(point(0, "heartbeat_time"), 100);
  EXPECT_EQ(wire_count("000#0102"), 1u);
}

TEST_F(CanBusTest, SlowerHeartbeatOfTheDeviceIsOverwritten) {
  auto nc = as_shipped();
  nc.heartbeat_ms = 1000;  // longer than the 300 ms consumer time
  start("2", kCia301Node, kTiming, nc);
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5; })) << wire_text();
  EXPECT_EQ(wire_count(kHeartbeatWrite), 1u);
  EXPECT_TRUE(stays_online(0, 1500ms)) << image(0).counters.last_error_text;
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::heartbeat);
}

TEST_F(CanBusTest, StoppedNodeIsStartedBeforeItsConfiguration) {
  start("2", kCia301Node);
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5; }));
  EXPECT_EQ(submit(0, "nmt stop").status, Reply::Status::ok);
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 4; }));
  // The link goes and comes back: the node, stopped, would answer no 0x1017 write.
  wire_->down = true;
  ASSERT_TRUE(run_until([&] { return offline(0); }, 2s));
  const auto from = wire_->wire.size();
  wire_->down = false;
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5 && online(0); }, 3s))
      << wire_text();
  EXPECT_GE(wire_count(kHeartbeatWrite, from), 1u);
  EXPECT_TRUE(stays_online(0, 1s)) << image(0).counters.last_error_text;
}

TEST_F(CanBusTest, NodeWithoutHeartbeatObjectIsWatchedBySdo) {
  auto nc = as_shipped();
  nc.heartbeat_object = sim::canopen::HeartbeatObject::absent;
  capture_log();
  start("2", kCia301Node, kTiming, nc);
  // The write is refused with 0x06020000 (object does not exist).
  ASSERT_TRUE(run_until([&] { return wire_count("582#8017100000000206") == 1; })) << wire_text();
  EXPECT_TRUE(stays_online(0, 1500ms)) << image(0).counters.last_error_text;
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::sdo);
  EXPECT_EQ(wire_count("000#0102"), 1u);
  // No heartbeat: node guarding tells the NMT state.
  EXPECT_GE(wire_count("702#R"), 3u) << wire_text();
  EXPECT_EQ(point(0, "nmt_state"), 5);
  // Its SDO answers are its liveness: powered off, it goes offline by timeouts, and returns.
  sim_->execute("power-off 2");
  ASSERT_TRUE(run_until([&] { return offline(0); }, 3s));
  EXPECT_EQ(image(0).counters.last_error_text, "no SDO response");
  sim_->execute("power-on 2");
  ASSERT_TRUE(run_until([&] { return online(0); }, 3s));
  EXPECT_TRUE(stays_online(0, 1s));
  test::expect_contains(captured_log(),
                        {"node dev (2) did not take heartbeat producer time 0x1017 = 100 ms: SDO "
                         "abort 0x06020000 from node 2 for 0x1017:0: object does not exist"});
}

TEST_F(CanBusTest, NodeWithoutHeartbeatOrGuardingHasNoNmtState) {
  auto nc = as_shipped();
  nc.heartbeat_object = sim::canopen::HeartbeatObject::absent;
  nc.node_guarding = false;
  capture_log();
  start("2", kCia301Node, kTiming, nc);
  ASSERT_TRUE(run_until([&] { return wire_count("582#8017100000000206") == 1; })) << wire_text();
  // After one consumer time without a guarding answer, the state is unknown, not "boot-up".
  ASSERT_TRUE(run_until([&] { return !bus_->node_status(0).nmt_state.has_value(); }, 2s));
  EXPECT_FALSE(point(0, "nmt_state").has_value());
  EXPECT_TRUE(stays_online(0, 1s)) << image(0).counters.last_error_text;
  const auto guards = wire_count("702#R");
  EXPECT_GE(guards, 2u);
  run_until([] { return false; }, 500ms);
  EXPECT_EQ(wire_count("702#R"), guards);  // given up on
  test::expect_contains(captured_log(),
                        {"node dev (2) answers no node guarding either: its NMT state is unknown"});
}

TEST_F(CanBusTest, NodeThatSendsNoHeartbeatIsWatchedBySdo) {
  auto nc = as_shipped();
  nc.heartbeat_object = sim::canopen::HeartbeatObject::silent;  // takes 0x1017, sends nothing
  capture_log();
  start("2", kCia301Node, kTiming, nc);
  ASSERT_TRUE(run_until([&] { return wire_count("582#60171000.*") == 1; })) << wire_text();
  EXPECT_TRUE(stays_online(0, 1500ms)) << image(0).counters.last_error_text;
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::sdo);
  // Boot-up, then guarding only: every later state frame answers the RTR just before it.
  std::string last;
  int states = 0;
  for (const auto& f : wire_->wire) {
    if (f.rfind("702#", 0) != 0) continue;
    if (f != "702#R" && states++ > 0) {
      EXPECT_EQ(last, "702#R") << "unasked: " << f;
    }
    last = f;
  }
  EXPECT_GE(states, 3);
  EXPECT_EQ(point(0, "nmt_state"), 5);
  sim_->execute("power-off 2");
  ASSERT_TRUE(run_until([&] { return offline(0); }, 3s));
  EXPECT_EQ(image(0).counters.last_error_text, "no SDO response");
  test::expect_contains(captured_log(),
                        {"node dev (2) sent no heartbeat within 300 ms of its producer time 0x1017 "
                         "being set to 100 ms; liveness by SDO"});
}

TEST_F(CanBusTest, ConfirmedWriteIsThePointsValue) {
  start("2", kCia301Node);
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5; }));
  const auto polls = wire_count("602#4017100000000000");
  EXPECT_EQ(submit(0, "write heartbeat_time 250").status, Reply::Status::ok);
  EXPECT_EQ(point(0, "heartbeat_time"), 250);
  EXPECT_TRUE(stays_online(0, 800ms));
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::heartbeat);
  // The object form updates the point too. A PLC that turns the heartbeat off does not make the
  // node flap: its SDO answers keep it online.
  EXPECT_EQ(submit(0, "write 0x1017:0 UNSIGNED16 0").status, Reply::Status::ok);
  EXPECT_EQ(point(0, "heartbeat_time"), 0);
  EXPECT_TRUE(stays_online(0, 1s)) << image(0).counters.last_error_text;
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::sdo);
  EXPECT_EQ(wire_count("602#4017100000000000"), polls);  // no poll of it meanwhile (10 s class)
}

// A PLC's producer time is the node's: the consumer follows it (three producer times), and the
// bus's bring-up writes it again instead of its own.
TEST_F(CanBusTest, ProducerTimeAPlcWroteIsFollowedNotOverwritten) {
  start("2", kCia301Node);
  ASSERT_TRUE(run_until([&] {
    return point(0, "nmt_state") == 5 &&
           bus_->node_status(0).liveness == CanBus::Liveness::heartbeat;
  }));
  capture_log();
  ASSERT_EQ(submit(0, "write heartbeat_time 1000").status, Reply::Status::ok);
  const auto writes = wire_count("602#2B171000.*");
  // Longer than the configured 300 ms consumer time, three times over.
  EXPECT_TRUE(stays_online(0, 2500ms)) << image(0).counters.last_error_text;
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::heartbeat);
  EXPECT_EQ(wire_count("702#R"), 0u) << "guarded as a node without heartbeat";
  EXPECT_EQ(wire_count("602#2B171000.*"), writes) << wire_text();
  EXPECT_EQ(point(0, "heartbeat_time"), 1000);
  // The link goes and comes back: configured again with the PLC's 1000 ms, not 100 ms.
  wire_->down = true;
  ASSERT_TRUE(run_until([&] { return offline(0); }, 2s));
  const auto from = wire_->wire.size();
  wire_->down = false;
  ASSERT_TRUE(run_until([&] { return wire_count("602#2B171000E8030000", from) == 1; }, 3s))
      << wire_text();
  EXPECT_EQ(wire_count(kHeartbeatWrite, from), 0u);
  EXPECT_TRUE(stays_online(0, 2500ms)) << image(0).counters.last_error_text;
  test::expect_contains(captured_log(),
                        {"node dev (2) heartbeat producer time 0x1017 written by a command: 1000 "
                         "ms; consumer time 3000 ms from now on",
                         "node dev (2) heartbeat producer time 0x1017 set to 1000 ms (chosen by a "
                         "command; consumer 3000 ms)"});
}

// Node guarding stands in for a heartbeat; once one is configured again, it stops.
TEST_F(CanBusTest, NodeGuardingStopsWhenAHeartbeatIsConfiguredAgain) {
  start("2", kCia301Node);
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5; }));
  ASSERT_EQ(submit(0, "write heartbeat_time 0").status, Reply::Status::ok);
  ASSERT_TRUE(run_until([&] { return wire_count("702#R") >= 2; }, 2s)) << wire_text();
  ASSERT_EQ(submit(0, "write heartbeat_time 100").status, Reply::Status::ok);
  ASSERT_TRUE(
      run_until([&] { return bus_->node_status(0).liveness == CanBus::Liveness::heartbeat; }, 2s));
  run_until([] { return false; }, 100ms);  // a request already on its way
  const auto guards = wire_count("702#R");
  EXPECT_TRUE(stays_online(0, 1s)) << image(0).counters.last_error_text;
  EXPECT_EQ(wire_count("702#R"), guards) << wire_text();
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::heartbeat);
  EXPECT_EQ(point(0, "nmt_state"), 5);
}

// Issue 49: a node watched by SDO (a PLC set its producer time to 0) whose heartbeat another
// tool turns on: node guarding stops while the heartbeat comes, whoever set it, and starts
// again once it stops. Its plain heartbeats (no toggle bit) are no guard replies.
TEST_F(CanBusTest, NodeGuardingStopsWhenAnotherToolTurnsTheHeartbeatOn) {
  auto nc = as_shipped();
  nc.node_guarding = false;  // its only state frames are heartbeats
  capture_log();
  start("2", kCia301Node, kTiming, nc);
  ASSERT_TRUE(run_until([&] {
    return point(0, "nmt_state") == 5 &&
           bus_->node_status(0).liveness == CanBus::Liveness::heartbeat;
  }));
  ASSERT_EQ(submit(0, "write heartbeat_time 0").status, Reply::Status::ok);
  ASSERT_TRUE(run_until([&] { return wire_count("702#R") >= 1; }, 1s)) << wire_text();
  // Another tool sets 0x1017 = 100 ms, unknown to the gateway (guarding gives up after 300 ms
  // without a reply: the heartbeat comes before that).
  std::size_t from = wire_->wire.size();
  ASSERT_TRUE(sim_->from_other_tool("602#2B17100064000000"));
  ASSERT_TRUE(run_until([&] { return wire_count("702#05", from) >= 3; }, 1s)) << wire_text();
  const auto guards = wire_count("702#R");
  EXPECT_TRUE(stays_online(0, 1s)) << image(0).counters.last_error_text;
  EXPECT_EQ(wire_count("702#R"), guards) << wire_text();
  EXPECT_EQ(bus_->node_status(0).guard_replies, 0u);
  EXPECT_EQ(bus_->node_status(0).liveness, CanBus::Liveness::sdo);
  EXPECT_EQ(point(0, "nmt_state"), 5);
  // The other tool turns it off again: guarding resumes a consumer time later.
  from = wire_->wire.size();
  ASSERT_TRUE(sim_->from_other_tool("602#2B17100000000000"));
  EXPECT_TRUE(run_until([&] { return wire_count("702#R", from) >= 1; }, 1s)) << wire_text();
  EXPECT_TRUE(online(0));
  test::expect_contains(captured_log(),
                        {"node dev (2) sends heartbeats the gateway did not set up: node guarding "
                         "stops while they come",
                         "node dev (2) sent no heartbeat within 300 ms: node guarding again"});
}

// A node that guards and produces no heartbeat of its own: each reply carries the toggle bit
// expected, and each is taken.
TEST_F(CanBusTest, GuardRepliesWithTheirToggleAreTaken) {
  auto nc = as_shipped();
  nc.heartbeat_object = sim::canopen::HeartbeatObject::absent;
  start("2", kCia301Node, kTiming, nc);
  ASSERT_TRUE(run_until([&] { return bus_->node_status(0).guard_replies >= 4; }, 2s))
      << wire_text();
  EXPECT_GE(wire_count("702#85"), 1u);  // the toggle bit alternates
  EXPECT_GE(wire_count("702#05"), 1u);
  EXPECT_TRUE(stays_online(0, 500ms));
  EXPECT_EQ(point(0, "nmt_state"), 5);
}

// CiA 301 makes 0x1008 optional (canopend has none). The device's abort marks it absent: its
// points read 0 (the empty name), so every read-only point has a value and a PLC's one read of
// them all succeeds; it is polled no more, and its abort leaves a command's abort readable.
TEST_F(CanBusTest, ObjectTheDeviceLacksLeavesItsNeighboursReadable) {
  auto nc = as_shipped();
  nc.device_name_object = false;
  capture_log();
  start("2",
        "      - {name: dev, address: 2, model: canopen-cia301, unit_id: 1, "
        "poll: {identity: 200ms}}\n",
        kTiming, nc);
  const std::string name_upload = "602#4008100000000000";
  ASSERT_TRUE(run_until([&] { return wire_count("582#8008100000000206") == 1; })) << wire_text();
  const Model& model = *config_->gateway.buses[0].nodes[0].model;
  ASSERT_TRUE(run_until([&] {
    for (const auto& p : model.points)
      if (!p.writable() && !point(0, p.name)) return false;
    return true;
  })) << wire_text();
  for (int field = 0; field < 8; ++field)
    EXPECT_EQ(point(0, "device_name_" + std::to_string(field)), 0);
  EXPECT_EQ(point(0, "sdo_abort_code"), 0);
  EXPECT_EQ(image(0).counters.last_device_error, 0);
  EXPECT_EQ(image(0).counters.errors, 0u);
  const ProcessImage diagnostics(bus_->node_images());
  EXPECT_NE(
      diagnostics.diagnostic(0, DiagnosticField::data_age_ms, std::chrono::steady_clock::now()),
      0xffffffff);
  // A command's abort stays in the diagnostics over several identity periods.
  const auto r = submit(0, "write 0x1000:0 UNSIGNED32 5");
  EXPECT_EQ(r.device_code, 0x06010002) << r.text;  // read only
  const auto vendor_reads = wire_count("602#4018100100000000");
  run_until([] { return false; }, 1s);
  EXPECT_GE(wire_count("602#4018100100000000"), vendor_reads + 3) << "identity polls go on";
  EXPECT_EQ(wire_count(name_upload), 1u) << "absent, yet polled again";
  EXPECT_EQ(point(0, "sdo_abort_code"), 0x06010002);
  EXPECT_EQ(image(0).counters.last_device_error, 0x06010002);
  EXPECT_TRUE(online(0));
  const std::string said =
      "node 2: no object 0x1008:0 (SDO abort 0x06020000: object does not exist in the object "
      "dictionary): not polled any more, its points read as an empty string (0)";
  const auto log = captured_log();
  test::expect_contains(log, {said});
  EXPECT_EQ(log.find(said), log.rfind(said)) << "said more than once";
  // After a restart the device may have it: asked once more.
  sim_->execute("power-off 2");
  sim_->execute("power-on 2");
  EXPECT_TRUE(run_until([&] { return wire_count(name_upload) == 2; }, 2s)) << wire_text();
}

TEST_F(CanBusTest, EveryPollClassRunsAcrossOnlineTransitions) {
  // Seven identity objects spread over 1 s; the node is online only ~100 ms at a time.
  start("2",
        "      - {name: dev, address: 2, model: canopen-cia301, unit_id: 1, "
        "poll: {identity: 1s}}\n");
  for (int cycle = 0; cycle < 5; ++cycle) {
    ASSERT_TRUE(run_until([&] { return online(0); }, 3s)) << "cycle " << cycle;
    run_until([] { return false; }, 100ms);
    sim_->execute("power-off 2");
    ASSERT_TRUE(run_until([&] { return offline(0); }, 3s)) << "cycle " << cycle;
    sim_->execute("power-on 2");
  }
  ASSERT_TRUE(run_until([&] { return online(0); }, 3s));
  run_until([] { return false; }, 100ms);
  for (const char* object : {"001000", "181001", "181002", "181003", "181004", "081000", "171000"})
    EXPECT_GE(wire_count(std::string("602#40") + object + "00000000"), 1u)
        << "never read: " << object << "\n"
        << wire_text();
}

TEST_F(CanBusTest, NodeStayingPreOperationalWithAnErrorIsReported) {
  auto nc = as_shipped();
  nc.start_needs_no_error = true;
  nc.power_up_error = 0x5000;  // device hardware: error register 0x01 (generic)
  capture_log();
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n", kTiming, nc);
  ASSERT_TRUE(run_until([&] { return bus_->node_status(0).stays_pre_operational; })) << wire_text();
  EXPECT_EQ(point(0, "nmt_state"), 127);
  EXPECT_EQ(point(0, "error_register"), 0x01);
  EXPECT_NE(image(0).counters.last_error_text.find(
                "stays pre-operational after NMT start; error register 0x01 (generic)"),
            std::string::npos)
      << image(0).counters.last_error_text;
  // Not started again and again: it stays online, and one NMT start was sent.
  EXPECT_TRUE(stays_online(0, 1500ms));
  EXPECT_EQ(wire_count("000#0102"), 1u) << wire_text();
  // A fault reset clears its error register (EMCY error reset): the bus starts it once more.
  for (const char* step : {"write controlword 0x00", "write controlword 0x80"})
    EXPECT_EQ(submit(0, step).status, Reply::Status::ok) << step;
  ASSERT_TRUE(run_until([&] { return point(0, "nmt_state") == 5; })) << wire_text();
  EXPECT_EQ(wire_count("000#0102"), 2u);
  EXPECT_FALSE(bus_->node_status(0).stays_pre_operational);
  test::expect_contains(
      captured_log(), {"node axis2 (2) stays pre-operational after NMT start; error register 0x01 "
                       "(generic); not started again until its error register clears or it boots",
                       "node axis2 (2) error register cleared: NMT start again"});
}

TEST_F(CanBusTest, NodeStayingPreOperationalWithoutAnErrorIsReportedOnce) {
  // Error register clear after the reset, but the node still refuses: reported, not looped.
  auto nc = as_shipped();
  nc.start_needs_no_error = true;
  nc.power_up_error = 0x5000;
  start("2", "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n", kTiming, nc);
  ASSERT_TRUE(run_until([&] { return bus_->node_status(0).stays_pre_operational; }));
  // Another master stops the node's start: an error that never clears.
  sim_->execute("fault 2 0x2310");
  EXPECT_TRUE(stays_online(0, 1s));
  EXPECT_EQ(wire_count("000#0102"), 1u);
  EXPECT_EQ(point(0, "error_register"), 0x03);
}

}  // namespace
}  // namespace fieldgate

namespace fieldgate {
namespace {

TEST_F(CanBusTest, WireTraceShowsFramesWithNodeAndSdoOutcome) {
  std::vector<std::string> lines;
  WireTrace::set_sink([&](std::string_view line) { lines.emplace_back(line); });
  start("2,3", kTwoDrives);
  ASSERT_TRUE(run_until([&] { return online(0); }));
  bus_->trace().set_enabled(true);
  auto r = submit(0, "write modes_of_operation 3");  // refused by the simulator: an SDO abort
  EXPECT_EQ(r.status, Reply::Status::device_error);
  bus_->trace().set_enabled(false);
  WireTrace::set_sink({});
  // The download request to node 2 (0x602) and the abort answering it (0x582, 0x80 first).
  const std::regex tx(R"(^trace can \(\d+\.\d{6}\) axis2 tx - '602#2F606000.*'$)");
  const std::regex rx(R"(^trace can \(\d+\.\d{6}\) axis2 rx device_error '582#80606000.*'$)");
  bool saw_tx = false, saw_rx = false;
  for (const auto& l : lines) {
    saw_tx = saw_tx || std::regex_match(l, tx);
    saw_rx = saw_rx || std::regex_match(l, rx);
  }
  std::string all;
  for (const auto& l : lines) all += l + "\n";
  EXPECT_TRUE(saw_tx) << all;
  EXPECT_TRUE(saw_rx) << all;
}

// Issue 31, item 3: a reload that changes one node's poll period is applied to that node alone:
// the interface is not reopened, both nodes stay online, and the new period is what the node is
// polled at. A node added is not taken in place (the receive filter names every node).
TEST_F(CanBusTest, ANodesPollPeriodChangeIsAppliedInPlace) {
  const std::string nodes =
      "      - {name: a, address: 2, model: canopen-cia301, unit_id: 1}\n"
      "      - {name: b, address: 3, model: canopen-cia301, unit_id: 2}\n";
  start("2,3", nodes);
  ASSERT_TRUE(run_until([&] { return online(0) && online(1); }));
  run_until([] { return false; }, 300ms);  // the identity class (10 s) has had its first round
  const auto images = bus_->node_images();
  const std::string a_identity = "602#4018100[1-4]00000000";
  const std::string b_identity = "603#4018100[1-4]00000000";
  const std::size_t from = wire_->wire.size();

  const auto next = load("gw2.yaml",
                         "      - {name: a, address: 2, model: canopen-cia301, unit_id: 1, "
                         "poll: {identity: 100ms}}\n"
                         "      - {name: b, address: 3, model: canopen-cia301, unit_id: 2}\n");
  ASSERT_TRUE(next);
  ASSERT_TRUE(bus_->reconfigure(next, next->gateway.buses[0], 0, [this](int) { ++updates_; }));
  EXPECT_EQ(bus_->node_images(), images) << "the same nodes, with their images";

  EXPECT_TRUE(stays_online(0, 600ms) && online(1));
  EXPECT_GE(wire_count(a_identity, from), 8u) << "a's identity objects, every 100 ms now";
  // b's seven identity objects keep their places in its 10 s (one every 1.4 s or so).
  EXPECT_LE(wire_count(b_identity, from), 1u) << "b keeps its 10 s";
  EXPECT_EQ(bus_->counters().reconnects, 1u) << "the interface was not reopened";

  const auto third = load(
      "gw3.yaml", nodes + "      - {name: c, address: 4, model: canopen-cia301, unit_id: 3}\n");
  ASSERT_TRUE(third);
  EXPECT_FALSE(bus_->reconfigure(third, third->gateway.buses[0], 0, nullptr));
  EXPECT_EQ(bus_->config().nodes.size(), 2u);
}

}  // namespace
}  // namespace fieldgate
