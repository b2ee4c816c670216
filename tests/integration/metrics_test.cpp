// The metrics endpoint scraped over HTTP and parsed as Prometheus text format.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <map>
#include <regex>

#include "harness.hpp"

namespace fieldgate::test {
namespace {

// name{labels} -> value; fails the test on any line that is not valid exposition format.
std::map<std::string, double> parse_exposition(const std::string& body) {
  static const std::regex sample(
      R"(^([a-zA-Z_:][a-zA-Z0-9_:]*(\{([a-zA-Z_][a-zA-Z0-9_]*="([^"\\]|\\.)*",?)*\})?) ([-+0-9.eE]+|\+Inf|NaN)$)");
  static const std::regex comment(R"(^# (HELP|TYPE) [a-zA-Z_:][a-zA-Z0-9_:]* .+$)");
  std::map<std::string, double> samples;
  std::size_t start = 0;
  while (start < body.size()) {
    const auto end = body.find('\n', start);
    const std::string line = body.substr(start, end - start);
    start = end == std::string::npos ? body.size() : end + 1;
    if (line.empty()) continue;
    std::smatch m;
    if (std::regex_match(line, comment)) continue;
    EXPECT_TRUE(std::regex_match(line, m, sample)) << "not exposition format: " << line;
    if (!m.empty()) samples[m[1]] = std::stod(m[5]);
  }
  return samples;
}

// Sends `request` to the loopback port and returns what came back until the server closed.
std::string raw_exchange(int port, const std::string& request) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string reply;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
      ::send(fd, request.data(), request.size(), MSG_NOSIGNAL) ==
          static_cast<ssize_t>(request.size())) {
    ::shutdown(fd, SHUT_WR);
    char buffer[4096];
    ssize_t n;
    while ((n = ::recv(fd, buffer, sizeof buffer, 0)) > 0) reply.append(buffer, std::size_t(n));
  }
  ::close(fd);
  return reply;
}

TEST(Metrics, ScrapedAndParsed) {
  SimulatedBus bus;
  bus.name = "copley";
  bus.protocol = "copley-ascii";
  bus.sim_argv = {FIELDGATE_SIM_COPLEY, "--link", "{link}", "--nodes", "0"};
  bus.nodes =
      "      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1}\n"
      "      - {name: amp9, address: 9, model: copley-amplifier, unit_id: 2}\n";
  // The metrics key is top-level; the harness inserts this text inside `modbus:`, so close it.
  Plant plant({bus}, "metrics:\n  listen: 127.0.0.1:0\n");
  const std::regex listening("metrics: http://127.0.0.1:([0-9]+)/metrics");
  std::smatch m;
  ASSERT_TRUE(wait_until([&] {
    const std::string log = plant.daemon().log();
    return std::regex_search(log, m, listening);
  }));
  const std::string log = plant.daemon().log();
  std::regex_search(log, m, listening);
  const int port = std::stoi(m[1]);

  ModbusClient client("127.0.0.1", plant.port());
  ASSERT_TRUE(wait_until([&] { return client.read_input(1, 0, 2).ok(); }));
  ASSERT_TRUE(
      wait_until([&] { return client.read_input(2, 1014, 1).values == std::vector<uint16_t>{2}; }));
  // The log names the cause of amp9's going offline apart from a timeout, as the metrics do.
  EXPECT_TRUE(wait_until([&] {
    return plant.daemon().log().find("node amp9 (9) offline: unreachable (e 32:") !=
           std::string::npos;
  })) << plant.daemon().log();
  for (int i = 0; i < 7; ++i) client.read_input(1, 0, 2);
  client.read_input(1, 600, 1);  // one exception

  // A request line that is not HTTP: answered 400, and counted.
  EXPECT_NE(raw_exchange(port, "BOGUS\r\n\r\n").find(" 400 "), std::string::npos);

  const std::string response = http_get(port, "/metrics");
  ASSERT_NE(response.find("HTTP/1.1 200 OK"), std::string::npos) << response;
  ASSERT_NE(response.find("text/plain; version=0.0.4"), std::string::npos);
  const auto body = response.substr(response.find("\r\n\r\n") + 4);
  const auto s = parse_exposition(body);

  EXPECT_EQ(s.at("fieldgate_build_info{version=\"0.1.0\"}"), 1);
  EXPECT_EQ(s.at("fieldgate_bus_up{bus=\"copley\"}"), 1);
  // One scrape is one consistent snapshot: the bus total is the sum over its nodes. The waits
  // above guarantee amp9's three timeouts (offline_after) and one poll answered by amp0; how many
  // more ran by now depends on how fast the machine is.
  EXPECT_GE(s.at("fieldgate_bus_transactions_total{bus=\"copley\"}"), 4);
  EXPECT_EQ(s.at("fieldgate_bus_transactions_total{bus=\"copley\"}"),
            s.at("fieldgate_node_transactions_total{bus=\"copley\",node=\"amp0\",unit=\"1\","
                 "listener=\"default\"}") +
                s.at("fieldgate_node_transactions_total{bus=\"copley\",node=\"amp9\",unit=\"2\","
                     "listener=\"default\"}"));
  EXPECT_GT(s.at("fieldgate_bus_sent_bytes_total{bus=\"copley\"}"), 50);
  EXPECT_EQ(
      s.at("fieldgate_node_online{bus=\"copley\",node=\"amp0\",unit=\"1\",listener=\"default\"}"),
      1);
  EXPECT_EQ(
      s.at("fieldgate_node_online{bus=\"copley\",node=\"amp9\",unit=\"2\",listener=\"default\"}"),
      0);
  // The gateway amplifier answers e 32 for amp9 (absent from its CAN network): unreachable, not
  // timeouts, and no CAN series on this serial bus.
  EXPECT_GE(s.at("fieldgate_node_unreachable_total{bus=\"copley\",node=\"amp9\",unit=\"2\","
                 "listener=\"default\"}"),
            3);
  EXPECT_EQ(s.at("fieldgate_node_timeouts_total{bus=\"copley\",node=\"amp9\",unit=\"2\","
                 "listener=\"default\"}"),
            0);
  EXPECT_EQ(s.count("fieldgate_bus_can_frames_sent_total{bus=\"copley\"}"), 0u);
  EXPECT_GT(s.at("process_resident_memory_bytes"), 0);
  EXPECT_GT(s.at("process_open_fds"), 0);
  EXPECT_LT(s.at("fieldgate_node_last_good_poll_age_seconds{bus=\"copley\",node=\"amp0\",unit="
                 "\"1\",listener=\"default\"}"),
            2);
  EXPECT_EQ(s.count("fieldgate_node_last_good_poll_age_seconds{bus=\"copley\",node=\"amp9\",unit="
                    "\"2\",listener=\"default\"}"),
            0u);
  EXPECT_GE(s.at("fieldgate_modbus_requests_total{listener=\"default\",function=\"4\"}"), 9);
  EXPECT_GE(
      s.at("fieldgate_modbus_exceptions_total{listener=\"default\",function=\"4\",code=\"2\"}"),
      1);  // 600 unmapped
  EXPECT_EQ(s.at("fieldgate_modbus_clients{listener=\"default\"}"), 1);
  // Histogram: cumulative buckets, +Inf equals the count.
  double previous = 0;
  for (const char* le :
       {"0.001", "0.002", "0.005", "0.01", "0.02", "0.05", "0.1", "0.2", "0.5", "1", "+Inf"}) {
    const double v = s.at(
        std::string("fieldgate_bus_transaction_seconds_bucket{bus=\"copley\",le=\"") + le + "\"}");
    EXPECT_GE(v, previous) << le;
    previous = v;
  }
  EXPECT_EQ(previous, s.at("fieldgate_bus_transaction_seconds_count{bus=\"copley\"}"));
  EXPECT_EQ(s.at("fieldgate_http_bad_requests_total{server=\"metrics\"}"), 1);
  EXPECT_EQ(s.at("fieldgate_http_denied_total{server=\"metrics\"}"), 0);
  EXPECT_EQ(s.at("fieldgate_http_connections_evicted_total{server=\"metrics\"}"), 0);
  EXPECT_EQ(s.at("fieldgate_http_connections_refused_total{server=\"console\"}"), 0);

  EXPECT_NE(http_get(port, "/").find("404"), std::string::npos);
}

TEST(Metrics, DisabledByDefault) {
  SimulatedBus bus;
  bus.name = "copley";
  bus.protocol = "copley-ascii";
  bus.sim_argv = {FIELDGATE_SIM_COPLEY, "--link", "{link}", "--nodes", "0"};
  bus.nodes = "      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1}\n";
  Plant plant({bus});
  EXPECT_EQ(plant.daemon().log().find("metrics:"), std::string::npos);
}

}  // namespace
}  // namespace fieldgate::test
