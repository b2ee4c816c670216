// The SocketCAN transport and the CAN bus runtime on a kernel vcan0 against
// fieldgate-sim-canopen, with candump as the foreign observer of the exact frames. Runs inside
// scripts/vcan-run (one User-Mode Linux boot for all of these tests, in order); the last tests
// take the interface down and delete it.
#include <gtest/gtest.h>

#include <fmt/format.h>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include "compiled_request.hpp"
#include "gateway/bus/can_bus.hpp"
#include "gateway/config/config_loader.hpp"
#include "vcan_fixture.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using test::can_interface;

class VcanBus : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!test::begin_suite(s, "2,3")) return;
    std::ofstream(s->dir / "gw.yaml")
        << "models: " FIELDGATE_SOURCE_DIR "/config/models\n"
        << "buses:\n  - name: can\n    protocol: canopen\n"
        << "    can: {interface: " << can_interface() << "}\n"
        << "    timing: {reply_timeout: 300ms, retries: 1, offline_after: 3, probe_interval: "
           "300ms, "
           "heartbeat_timeout: 1s, start_nodes: true, reconnect_min: 100ms, "
           "reconnect_max: 500ms}\n"
        << "    nodes:\n"
        << "      - {name: axis2, address: 2, model: canopen-cia402, unit_id: 1}\n"
        << "      - {name: axis3, address: 3, model: canopen-cia402, unit_id: 2}\n";
    Diagnostics d;
    auto loaded = load_gateway_config((s->dir / "gw.yaml").string(), d);
    if (!loaded) {
      s->error = d.to_text();
      return;
    }
    s->config = std::make_shared<LoadedConfig>(std::move(*loaded));
    s->bus = std::make_shared<CanBus>(s->io.get_executor(), s->config, s->config->gateway.buses[0],
                                      0, nullptr);
    asio::co_spawn(
        s->io, [bus = s->bus]() -> asio::awaitable<void> { co_await bus->run(); }, asio::detached);
  }
  static void TearDownTestSuite() {
    if (!s) return;
    if (s->bus) {
      s->bus->stop();
      s->io.run_for(200ms);
    }
    delete s;
    s = nullptr;
  }
  void SetUp() override {
    ASSERT_TRUE(test::vcan_present());
    ASSERT_TRUE(test::suite_ready(s));
  }

  static bool run_until(const std::function<bool()>& pred, std::chrono::milliseconds limit = 20s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      if (pred()) return true;
      s->io.run_for(5ms);
    }
    return pred();
  }
  // `command` compiled against the node's model, as the gateway compiles a model's templates.
  static Request request(int node, const std::string& command) {
    const auto& model = *s->config->gateway.buses[0].nodes.at(static_cast<size_t>(node)).model;
    return test::compiled_request(command, &model);
  }
  static Reply submit(int node, const std::string& command) {
    std::optional<Reply> reply;
    asio::co_spawn(
        s->io,
        [&]() -> asio::awaitable<void> {
          const Request r = request(node, command);
          reply = co_await s->bus->submit(node, r);
        },
        asio::detached);
    run_until([&] { return reply.has_value(); }, 30s);
    if (!reply) return Reply{Reply::Status::timeout, {}, 0, "test: no reply"};
    return *reply;
  }
  static const NodeImage& image(int node) {
    return *s->bus->node_images().at(static_cast<std::size_t>(node));
  }
  static bool online(int node) { return image(node).state == NodeState::online; }
  static bool offline(int node) { return image(node).state == NodeState::offline; }
  // Node 2's SDO frames from index `from` on, in candump text.
  static std::vector<std::string> sdo_frames(std::size_t from, int node = 2) {
    const auto tx = fmt::format("{:03X}#", 0x600 + node), rx = fmt::format("{:03X}#", 0x580 + node);
    std::vector<std::string> out;
    const auto all = s->candump->frames();
    for (std::size_t i = from; i < all.size(); ++i)
      if (all[i].rfind(tx, 0) == 0 || all[i].rfind(rx, 0) == 0) out.push_back(all[i]);
    return out;
  }
  // Waits until node 2's SDO frames from index `from` on hold `expected` in a row.
  static bool sdo_sequence_seen(std::size_t from, const std::vector<std::string>& expected) {
    return run_until([&] {
      const auto f = sdo_frames(from);
      return std::search(f.begin(), f.end(), expected.begin(), expected.end()) != f.end();
    });
  }

  struct Shared : test::VcanSuite {
    std::shared_ptr<const LoadedConfig> config;
    asio::io_context io;
    std::shared_ptr<CanBus> bus;
  };
  static Shared* s;
};

VcanBus::Shared* VcanBus::s = nullptr;

TEST_F(VcanBus, TransportFiltersAndErrorFrames) {
  asio::io_context io;
  SocketCanTransport missing(io.get_executor(), "nosuchcan7");
  EXPECT_EQ(missing.open({0x123}), std::make_error_code(std::errc::no_such_device));
  SocketCanTransport t(io.get_executor(), can_interface());
  ASSERT_FALSE(t.open({0x123, 0x7FE}));
  ASSERT_TRUE(test::raw_send(*parse_frame("124#01")));
  ASSERT_TRUE(test::raw_send(*parse_frame("123#CAFE")));
  ASSERT_TRUE(test::raw_send(*parse_frame("20000040#0000000000000000")));  // bus-off
  ASSERT_TRUE(test::raw_send(*parse_frame("7FE#R")));  // remote frames do not pass the filter
  ASSERT_TRUE(test::raw_send(*parse_frame("7FE#11")));
  std::vector<CanFrame> got;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (got.size() < 3 && std::chrono::steady_clock::now() < deadline) {
    std::vector<CanFrame> batch;
    asio::co_spawn(
        io,
        [&]() -> asio::awaitable<void> {
          const auto ec = co_await t.receive(batch);
          EXPECT_FALSE(ec) << ec.message();
        },
        asio::detached);
    io.run_for(1s);
    io.restart();
    got.insert(got.end(), batch.begin(), batch.end());
  }
  ASSERT_EQ(got.size(), 3u);  // 0x124 and the remote frame are filtered out by the kernel
  EXPECT_EQ(to_string(got[0]), "123#CAFE");
  EXPECT_TRUE(got[1].error);
  EXPECT_TRUE(decode_error_frame(got[1]).bus_off);
  EXPECT_EQ(to_string(got[2]), "7FE#11");
  EXPECT_EQ(t.stats().error_frames, 1u);
  EXPECT_EQ(t.stats().frames_received, 2u);
  // Sending goes out on the wire where candump sees it.
  const auto mark = s->candump->size();
  std::error_code sent;
  asio::co_spawn(
      io, [&]() -> asio::awaitable<void> { sent = co_await t.send(*parse_frame("7FD#0102"), 1s); },
      asio::detached);
  io.run_for(1s);
  EXPECT_FALSE(sent);
  EXPECT_TRUE(run_until([&] { return s->candump->count("7FD#0102", mark) == 1; }));
}

TEST_F(VcanBus, NodesStartAndComeOnline) {
  ASSERT_TRUE(run_until([&] { return online(0) && online(1); })) << s->candump->text();
  EXPECT_TRUE(run_until(
      [&] { return s->candump->count("000#0102") >= 1 && s->candump->count("000#0103") >= 1; }));
  EXPECT_TRUE(run_until([&] { return s->bus->node_status(0).nmt_state == 5; }));
  EXPECT_TRUE(run_until([&] { return s->bus->node_status(0).pdos > 0; }));
  EXPECT_TRUE(s->bus->counters().link_up);
}

TEST_F(VcanBus, SegmentedUploadExactFrames) {
  ASSERT_TRUE(run_until([&] { return online(0); }));
  const auto mark = s->candump->size();
  const auto r = submit(0, "read 0x1008:0 VISIBLE_STRING");
  ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
  EXPECT_EQ(r.text, "fieldgate sim CiA 402 drive");
  const std::vector<std::string> expected{"602#4008100000000000", "582#410810001B000000",
                                          "602#6000000000000000", "582#006669656C646761",
                                          "602#7000000000000000", "582#1074652073696D20",
                                          "602#6000000000000000", "582#0043694120343032",
                                          "602#7000000000000000", "582#1320647269766500"};
  ASSERT_TRUE(sdo_sequence_seen(mark, expected)) << s->candump->text(mark);
}

TEST_F(VcanBus, SegmentedDownloadExactFramesAndReadBack) {
  ASSERT_TRUE(run_until([&] { return online(0); }));
  const auto mark = s->candump->size();
  auto r = submit(0, "write 0x2000:0 VISIBLE_STRING \"fieldgate axis two\"");
  ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
  const std::vector<std::string> expected{"602#2100200012000000", "582#6000200000000000",
                                          "602#006669656C646761", "582#2000000000000000",
                                          "602#1074652061786973", "582#3000000000000000",
                                          "602#072074776F000000", "582#2000000000000000"};
  ASSERT_TRUE(sdo_sequence_seen(mark, expected)) << s->candump->text(mark);
  r = submit(0, "read 0x2000:0 VISIBLE_STRING");
  EXPECT_EQ(r.text, "fieldgate axis two");
  // Expedited both ways.
  r = submit(0, "write 0x1017:0 UNSIGNED16 100");
  EXPECT_EQ(r.status, Reply::Status::ok) << r.text;
  r = submit(0, "read 0x1017:0 UNSIGNED16");
  ASSERT_EQ(r.values.size(), 1u);
  EXPECT_EQ(r.values[0], 100);
  // candump is another process on the same vcan: its lines may trail the bus's own reception.
  EXPECT_TRUE(run_until([&] {
    return s->candump->count("602#2B17100064000000", mark) >= 1 &&
           s->candump->count("582#4B17100064000000", mark) >= 1;
  })) << s->candump->text(mark);
}

TEST_F(VcanBus, AbortCodesBecomeDeviceErrors) {
  ASSERT_TRUE(run_until([&] { return online(0); }));
  const auto mark = s->candump->size();
  auto r = submit(0, "read 0x1234:0 UNSIGNED8");
  EXPECT_EQ(r.status, Reply::Status::device_error);
  EXPECT_EQ(r.device_code, 0x06020000);
  EXPECT_NE(r.text.find("object does not exist in the object dictionary"), std::string::npos);
  r = submit(0, "write 0x1000:0 UNSIGNED32 1");
  EXPECT_EQ(r.device_code, 0x06010002);
  EXPECT_NE(r.text.find("attempt to write a read only object"), std::string::npos);
  r = submit(0, "write modes_of_operation 3");
  EXPECT_EQ(r.device_code, 0x06090030);
  EXPECT_EQ(s->bus->node_status(0).last_abort, 0x06090030u);
  EXPECT_TRUE(run_until([&] { return s->candump->count("582#8034120000000206", mark); }));
}

TEST_F(VcanBus, TransfersToDifferentNodesOverlap) {
  ASSERT_TRUE(run_until([&] { return online(0) && online(1); }));
  const auto mark = s->candump->size();
  // Two long transfers submitted together: node 3's starts before node 2's has ended.
  std::optional<Reply> a, b;
  for (int node = 0; node < 2; ++node) {
    std::optional<Reply>* out = node == 0 ? &a : &b;
    asio::co_spawn(
        s->io,
        [node, out]() -> asio::awaitable<void> {
          const Request r = request(node, "read 0x1008:0 VISIBLE_STRING");
          *out = co_await s->bus->submit(node, r);
        },
        asio::detached);
  }
  ASSERT_TRUE(run_until([&] { return a && b; }));
  EXPECT_EQ(a->text, "fieldgate sim CiA 402 drive");
  EXPECT_EQ(b->text, "fieldgate sim CiA 402 drive");
  // candump is another process: its lines may trail the bus's own reception, so both transfers'
  // last segments must be in its log before the order is read from it.
  ASSERT_TRUE(run_until([&] {
    return s->candump->count("582#1320647269766500", mark) >= 1 &&
           s->candump->count("583#1320647269766500", mark) >= 1;
  })) << s->candump->text(mark);
  const auto f = s->candump->frames();
  std::size_t first_2 = f.size(), last_2 = 0, first_3 = f.size();
  std::map<std::string, int> outstanding;
  for (std::size_t i = mark; i < f.size(); ++i) {
    if (f[i] == "602#4008100000000000" && first_2 == f.size()) first_2 = i;
    if (f[i] == "603#4008100000000000" && first_3 == f.size()) first_3 = i;
    if (f[i] == "582#1320647269766500") last_2 = i;
    // One transfer per node: a request never follows a request of the same node.
    const std::string id = f[i].substr(0, 3);
    if (id == "602" || id == "603") {
      EXPECT_EQ(outstanding[id], 0) << "second request in flight at " << i << ": " << f[i];
      outstanding[id] = 1;
    } else if (id == "582" || id == "583") {
      outstanding[id == "582" ? "602" : "603"] = 0;
    }
  }
  EXPECT_LT(first_2, last_2);
  EXPECT_LT(first_3, last_2) << "node 3's transfer did not overlap node 2's\n"
                             << s->candump->text(mark);
}

TEST_F(VcanBus, EmergencyIsConsumed) {
  ASSERT_TRUE(run_until([&] { return online(0); }));
  s->sim->command("fault 2 0x3210");
  ASSERT_TRUE(run_until([&] { return s->bus->node_status(0).emcy_code == 0x3210; }));
  EXPECT_EQ(s->bus->node_status(0).emcy_register, 0x05);  // generic + voltage
  EXPECT_EQ(image(0).counters.last_device_error, 0x3210);
  EXPECT_NE(image(0).counters.last_error_text.find("voltage inside the device"), std::string::npos)
      << image(0).counters.last_error_text;
  for (const char* step : {"write controlword 0x00", "write controlword 0x80"})
    EXPECT_EQ(submit(0, step).status, Reply::Status::ok) << step;
  EXPECT_TRUE(run_until([&] { return s->bus->node_status(0).emcy_code == 0; }));
}

TEST_F(VcanBus, ErrorFramesAreCounted) {
  const auto before = *s->bus->can_counters();
  ASSERT_TRUE(test::raw_send(*parse_frame("20000004#0030000000000000")));  // error passive
  ASSERT_TRUE(test::raw_send(*parse_frame("20000040#0000000000000000")));  // bus-off
  ASSERT_TRUE(
      run_until([&] { return s->bus->can_counters()->error_frames >= before.error_frames + 2; }));
  EXPECT_EQ(s->bus->can_counters()->bus_off, before.bus_off + 1);
  EXPECT_TRUE(s->bus->counters().link_up);
}

TEST_F(VcanBus, HeartbeatLossAndReturn) {
  ASSERT_TRUE(run_until([&] { return online(1); }));
  s->sim->command("power-off 3");
  ASSERT_TRUE(run_until([&] { return offline(1); }));
  EXPECT_TRUE(online(0));
  EXPECT_EQ(submit(1, "read 0x1000:0 UNSIGNED32").status, Reply::Status::unreachable);
  const auto mark = s->candump->size();
  s->sim->command("power-on 3");
  ASSERT_TRUE(run_until([&] { return online(1); }));
  EXPECT_TRUE(run_until([&] { return s->candump->count("000#0103", mark) >= 1; }))
      << s->candump->text(mark);
  EXPECT_TRUE(run_until([&] { return s->bus->node_status(1).nmt_state == 5; }));
}

TEST_F(VcanBus, InterfaceDownAndUp) {
  ASSERT_TRUE(run_until([&] { return online(0) && online(1); }));
  const auto reconnects = s->bus->counters().reconnects;
  ASSERT_EQ(test::shell(std::string("ip link set ") + can_interface() + " down"), 0);
  ASSERT_TRUE(run_until([&] { return !s->bus->counters().link_up && offline(0) && offline(1); }));
  EXPECT_EQ(submit(0, "read 0x1000:0 UNSIGNED32").text, "bus link is down");
  run_until([] { return false; }, 1s);  // reopening fails while the interface is down
  EXPECT_EQ(s->bus->counters().reconnects, reconnects);
  ASSERT_EQ(test::shell(std::string("ip link set ") + can_interface() + " up"), 0);
  ASSERT_TRUE(run_until([&] { return s->bus->counters().link_up && online(0) && online(1); }))
      << s->sim->log();
  EXPECT_EQ(s->bus->counters().reconnects, reconnects + 1);
  EXPECT_EQ(submit(0, "read 0x1000:0 UNSIGNED32").status, Reply::Status::ok);
}

TEST_F(VcanBus, InterfaceVanishesAndReturns) {
  ASSERT_TRUE(run_until([&] { return online(0); }));
  const auto reconnects = s->bus->counters().reconnects;
  const std::string ifname = can_interface();
  ASSERT_EQ(test::shell("ip link del " + ifname), 0);
  ASSERT_TRUE(run_until([&] { return !s->bus->counters().link_up && offline(0); }));
  run_until([] { return false; }, 1s);
  ASSERT_EQ(test::shell("ip link add dev " + ifname + " type vcan && ip link set up " + ifname), 0);
  // The simulator's socket went with the old interface: start a new one.
  s->sim = std::make_unique<test::CanopenSim>(s->dir, "2,3", "sim-again");
  ASSERT_TRUE(s->sim->wait_ready()) << s->sim->log();
  ASSERT_TRUE(run_until([&] { return s->bus->counters().link_up && online(0) && online(1); }));
  EXPECT_EQ(s->bus->counters().reconnects, reconnects + 1);
  EXPECT_EQ(submit(0, "read 0x1000:0 UNSIGNED32").values.at(0), 0x00020192);
}

}  // namespace
}  // namespace fieldgate
