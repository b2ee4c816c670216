// The daemon as systemd runs it: sd_notify messages on a NOTIFY_SOCKET, reload on SIGHUP.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <csignal>
#include <fstream>
#include <sstream>

#include "harness.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// A NOTIFY_SOCKET: a datagram socket collecting what the daemon sends.
class NotifySocket {
 public:
  explicit NotifySocket(const std::filesystem::path& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
      throw std::runtime_error("cannot bind notify socket");
  }
  ~NotifySocket() { ::close(fd_); }
  // Reads everything that arrived since the last call, appending to the message list.
  const std::vector<std::string>& messages() {
    char buf[4096];
    ssize_t n;
    while ((n = ::recv(fd_, buf, sizeof buf, 0)) > 0)
      messages_.emplace_back(buf, static_cast<std::size_t>(n));
    return messages_;
  }
  int count(const std::string& needle) {
    int c = 0;
    for (const auto& m : messages())
      if (m.find(needle) != std::string::npos) ++c;
    return c;
  }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  std::vector<std::string> messages_;
};

const char* kNodes =
    "      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1}\n"
    "      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2}\n";

SimulatedBus copley_bus() {
  SimulatedBus bus;
  bus.name = "copley";
  bus.protocol = "copley-ascii";
  bus.sim_argv = {FIELDGATE_SIM_COPLEY, "--link", "{link}", "--nodes", "0,3"};
  bus.nodes = kNodes;
  return bus;
}

std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

uint32_t transactions(ModbusClient& c, int unit) {
  auto r = c.read_input(unit, 1004, 2);
  return r.ok() ? (static_cast<uint32_t>(r.values[0]) << 16) | r.values[1] : 0;
}

class ServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    socket_path_ = std::filesystem::temp_directory_path() /
                   ("fieldgate-notify-" + std::to_string(::getpid()) + "-" +
                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
    notify_ = std::make_unique<NotifySocket>(socket_path_);
    plant_ = std::make_unique<Plant>(
        std::vector<SimulatedBus>{copley_bus()}, "",
        std::vector<std::string>{"NOTIFY_SOCKET=" + socket_path_.string(), "WATCHDOG_USEC=200000"});
    client_ = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
    ASSERT_TRUE(wait_until([&] { return client_->read_input(2, 0, 2).ok(); }));
  }
  void TearDown() override {
    if (HasFailure() && plant_) std::cerr << "--- daemon log ---\n" << plant_->daemon().log();
    client_.reset();
    plant_.reset();
    notify_.reset();
    std::filesystem::remove(socket_path_);
  }

  std::filesystem::path socket_path_;
  std::unique_ptr<NotifySocket> notify_;
  std::unique_ptr<Plant> plant_;
  std::unique_ptr<ModbusClient> client_;
};

TEST_F(ServiceTest, ReadyWatchdogStatusReloadingStopping) {
  ASSERT_TRUE(wait_until([&] { return notify_->count("READY=1") == 1; }));
  // The summary names the configuration in force first (issue 31), then the buses.
  EXPECT_EQ(notify_->count("buses up 1/1"), 1) << "READY carries the summary";
  EXPECT_EQ(notify_->count("STATUS=config #1 ("), 1) << "the status names the configuration";
  // WATCHDOG_USEC=200ms: a ping at least every 100 ms from the event loop.
  ASSERT_TRUE(wait_until([&] { return notify_->count("WATCHDOG=1") >= 5; }, 3s));
  plant_->daemon().signal(SIGHUP);
  ASSERT_TRUE(wait_until([&] { return notify_->count("READY=1") == 2; }));
  EXPECT_EQ(notify_->count("RELOADING=1"), 1);
  plant_->daemon().signal(SIGTERM);
  ASSERT_TRUE(wait_until([&] { return notify_->count("STOPPING=1") == 1; }));
  EXPECT_EQ(plant_->daemon().wait_exit(), 0);
}

TEST_F(ServiceTest, ReloadWithUnchangedBusKeepsClientAndPolling) {
  // Change something that is not the bus: the client limit.
  std::string config = read_file(plant_->config_path());
  const auto pos = config.find("  listen:");
  config.insert(pos, "  max_clients: 20\n");
  std::ofstream(plant_->config_path()) << config;
  const uint32_t before = transactions(*client_, 2);
  ASSERT_GT(before, 0u);
  plant_->daemon().signal(SIGHUP);
  ASSERT_TRUE(
      wait_until([&] { return plant_->daemon().log().find("reloaded:") != std::string::npos; }));
  EXPECT_NE(plant_->daemon().log().find("1 bus(es) kept running, 0 started, 0 stopped"),
            std::string::npos);
  // Same connection, node still online, counters continue (the bus was not restarted).
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(client_->read_input(2, 0, 2).ok());
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_GT(transactions(*client_, 2), before);
  EXPECT_EQ(client_->read_input(2, 1000, 1).values, std::vector<uint16_t>{1});
}

TEST_F(ServiceTest, MoveStartedBeforeAReloadCompletesAfterIt) {
  ASSERT_TRUE(client_->write_single(2, 100, 1).ok());   // enable
  ASSERT_TRUE(client_->write_i32(2, 110, 30000).ok());  // target: a move of about 3 s
  ASSERT_TRUE(client_->write_single(2, 100, 3).ok());   // move_absolute
  EXPECT_EQ(client_->read_holding(2, 101, 1).values, std::vector<uint16_t>{1});
  plant_->daemon().signal(SIGHUP);  // same file: the bus is kept
  // Keep reading the notify socket as systemd does: a full datagram queue would block the daemon.
  ASSERT_TRUE(wait_until([&] {
    notify_->messages();
    return plant_->daemon().log().find("reloaded:") != std::string::npos;
  }));
  ASSERT_TRUE(wait_until(
      [&] {
        notify_->messages();
        return client_->read_holding(2, 101, 1).values == std::vector<uint16_t>{2};
      },
      std::chrono::seconds(20)))
      << "the move's completion watch must survive the reload";
  EXPECT_EQ(client_->read_input_i32(2, 0), 30000);
}

TEST_F(ServiceTest, BadReloadKeepsTheRunningConfiguration) {
  std::string config = read_file(plant_->config_path());
  std::ofstream(plant_->config_path())
      << config << "      - {name: amp9, address: 300, model: copley-amplifier, unit_id: 9}\n";
  plant_->daemon().signal(SIGHUP);
  // The verdict is the last line of the rejection: wait for it, not for the first line.
  ASSERT_TRUE(wait_until([&] {
    return plant_->daemon().log().find(") stays in force") != std::string::npos;
  })) << plant_->daemon().log();
  const std::string log = plant_->daemon().log();
  EXPECT_NE(log.find("gateway.yaml:12:31: node amp9 address: Copley node ID must be 0..127"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("config #1 ("), std::string::npos);
  EXPECT_NE(log.find(") stays in force"), std::string::npos);
  EXPECT_TRUE(client_->read_input(2, 0, 2).ok());
  EXPECT_EQ(client_->read_input(9, 0, 2).exception, 0x0A);  // the rejected unit does not exist
  EXPECT_TRUE(plant_->daemon().running());
}

// Issue 31, item 3: a node's poll period changed and a node added. The bus takes both in place:
// its link is not reopened, and its other node answers every read across the reload.
TEST_F(ServiceTest, ANodeChangeIsAppliedToTheNodeAloneWithoutReopeningTheBus) {
  std::string config = read_file(plant_->config_path());
  const std::string amp3 =
      "      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2}\n";
  const auto at = config.find(amp3);
  ASSERT_NE(at, std::string::npos) << config;
  config.replace(at, amp3.size(),
                 "      - {name: amp7, address: 7, model: copley-amplifier, unit_id: 3}\n"
                 "      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2,"
                 " poll: {fast: 50ms}}\n");
  const auto count = [](const std::string& log, const std::string& what) {
    std::size_t n = 0;
    for (auto p = log.find(what); p != std::string::npos; p = log.find(what, p + 1)) ++n;
    return n;
  };
  const std::size_t opens_before = count(plant_->daemon().log(), "bus copley: opened");
  ASSERT_GE(opens_before, 1u) << "the bus logs its opening";
  const uint32_t before = transactions(*client_, 2);
  std::ofstream(plant_->config_path()) << config;
  plant_->daemon().signal(SIGHUP);
  int failed = 0, reads = 0;
  while (plant_->daemon().log().find("reloaded:") == std::string::npos && reads < 500) {
    failed += client_->read_input(2, 0, 2).ok() ? 0 : 1;
    ++reads;
    std::this_thread::sleep_for(5ms);
  }
  for (int i = 0; i < 40; ++i) {
    failed += client_->read_input(2, 0, 2).ok() ? 0 : 1;
    std::this_thread::sleep_for(10ms);
  }
  const std::string log = plant_->daemon().log();
  EXPECT_NE(log.find("1 bus(es) kept running, 0 started, 0 stopped (1 of them with node changes "
                     "applied in place)"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("bus copley: node amp7 (7) added"), std::string::npos);
  EXPECT_EQ(failed, 0) << "the unchanged neighbour answered every read";
  EXPECT_EQ(count(log, "bus copley: opened"), opens_before) << "the link was not reopened";
  EXPECT_GT(transactions(*client_, 2), before) << "its counters carry on";
  // The added node is polled: absent behind the amplifier, it goes offline (0x0B) on its own.
  EXPECT_TRUE(wait_until(
      [&] { return plant_->daemon().log().find("node amp7 (7) offline") != std::string::npos; }));
  EXPECT_EQ(client_->read_input(3, 0, 2).exception, 0x0B);
  EXPECT_TRUE(client_->read_input(2, 0, 2).ok());
}

TEST_F(ServiceTest, ReloadWithChangedBusReopensItAndKeepsTheClient) {
  std::string config = read_file(plant_->config_path());
  const auto pos = config.find("reply_timeout: 50ms");
  config.replace(pos, 19, "reply_timeout: 60ms");
  // Unit 2 moves to unit 5.
  const auto unit = config.find("unit_id: 2");
  config.replace(unit, 10, "unit_id: 5");
  std::ofstream(plant_->config_path()) << config;
  plant_->daemon().signal(SIGHUP);
  ASSERT_TRUE(
      wait_until([&] { return plant_->daemon().log().find("reloaded:") != std::string::npos; }));
  EXPECT_NE(plant_->daemon().log().find("0 bus(es) kept running, 1 started, 1 stopped"),
            std::string::npos);
  ASSERT_TRUE(wait_until([&] { return client_->read_input(5, 0, 2).ok(); }));
  EXPECT_EQ(client_->read_input(2, 0, 2).exception, 0x0A);
}

}  // namespace
}  // namespace fieldgate::test
