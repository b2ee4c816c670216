#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "gateway/bus/reply_accounting.hpp"
#include "gateway/config/config_loader.hpp"
#include "gateway/metrics/process_metrics.hpp"

namespace fieldgate {
namespace {

TEST(ProcStat, FieldsAfterACommandNameWithSpacesAndParentheses) {
  // proc(5): pid (comm) state ppid ... utime(14) stime(15) ... starttime(22) vsize(23) rss(24)
  const std::string text =
      "4242 (field gate (x)) S 1 4242 4242 0 -1 4194560 1000 0 0 0 250 50 0 0 20 0 2 0 12345 "
      "123456789 2000 18446744073709551615 1 1 0 0 0 0 0 0 0 0 0 0 17 1 0 0 0 0 0";
  ProcStat s;
  ASSERT_TRUE(parse_proc_stat(text, 100, 4096, s));
  EXPECT_DOUBLE_EQ(s.cpu_seconds, 3.0);  // (250 + 50) / 100
  EXPECT_DOUBLE_EQ(s.start_seconds, 123.45);
  EXPECT_DOUBLE_EQ(s.resident_bytes, 2000.0 * 4096);
  EXPECT_FALSE(parse_proc_stat("4242 (x) S 1 2 3", 100, 4096, s));
  EXPECT_FALSE(parse_proc_stat("no parenthesis", 100, 4096, s));
}

TEST(ProcStat, RendersTheProcessSeries) {
  const auto text = render_process_metrics();
  for (const char* name : {"process_cpu_seconds_total ", "process_resident_memory_bytes ",
                           "process_open_fds ", "process_start_time_seconds "})
    EXPECT_NE(text.find(std::string("\n") + name), std::string::npos) << name << "\n" << text;
}

TEST(ReplyAccounting, UnreachableIsCountedApartFromTimeoutsWithItsCode) {
  NodeCounters node;
  BusCounters bus;
  Reply r;
  r.status = Reply::Status::unreachable;
  r.device_code = 32;
  r.text = "e 32: CAN network communications failure";
  EXPECT_EQ(count_reply(node, bus, r, SteadyTime{}), ReplyOutcome::failed);
  EXPECT_EQ(node.unreachable, 1u);
  EXPECT_EQ(bus.unreachable, 1u);
  EXPECT_EQ(node.timeouts, 0u);
  EXPECT_EQ(bus.timeouts, 0u);
  EXPECT_EQ(node.consecutive_timeouts, 1u);  // still counts toward offline
  EXPECT_EQ(node.last_device_error, 32);
  r.status = Reply::Status::timeout;
  r.device_code = 0;
  count_reply(node, bus, r, SteadyTime{});
  EXPECT_EQ(node.timeouts, 1u);
  EXPECT_EQ(node.unreachable, 1u);
  EXPECT_EQ(node.consecutive_timeouts, 2u);
}

TEST(ConfigModels, AMissingRelativeModelsDirectoryNamesItsLocationAndResolvedPath) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("fieldgate-models-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const auto path = dir / "copied.yaml";
  std::ofstream(path) << "modbus: {listen: 127.0.0.1:0}\n"
                         "models: models\n"
                         "buses: []\n";
  Diagnostics d;
  EXPECT_FALSE(load_gateway_config(path.string(), d));
  const std::string text = d.to_text();
  fs::remove_all(dir);
  EXPECT_NE(text.find(path.string() + ":2:9: error: models: no directory " +
                      (dir / "models").string() + " ('models' is resolved from the directory"),
            std::string::npos)
      << text;
}

}  // namespace
}  // namespace fieldgate
