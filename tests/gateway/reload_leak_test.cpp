// Gateway::apply of an unchanged configuration, as a site's config management sends SIGHUP every
// few minutes: nothing of the configurations a reload replaced stays behind once nothing runs on
// them (issue 53: each reload kept its whole generation until the daemon stopped).
//
// Its own executable: it counts every live heap allocation of the process.
#include <gtest/gtest.h>

#include <boost/asio/io_context.hpp>

#include <atomic>
#include <cstdlib>
#include <new>

#include "config_file_test.hpp"
#include "gateway/gateway.hpp"

namespace {
std::atomic<long> g_live_allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  void* p = std::malloc(size == 0 ? 1 : size);
  if (!p) throw std::bad_alloc();
  g_live_allocations.fetch_add(1, std::memory_order_relaxed);
  return p;
}

void operator delete(void* p) noexcept {
  if (!p) return;
  g_live_allocations.fetch_sub(1, std::memory_order_relaxed);
  std::free(p);
}

void operator delete(void* p, std::size_t) noexcept {
  operator delete(p);
}

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
namespace asio = boost::asio;

class ReloadLeakTest : public test::ConfigFileTest {
 protected:
  // Two serial buses of two nodes each, on ports that do not exist (each bus keeps trying to open
  // its own), the Modbus listener, the metrics and the console on free ports.
  // `poll`: a node setting of a1 that a reload applies in place (its bus is reconfigured).
  std::shared_ptr<const LoadedConfig> config(const std::string& poll = "") {
    const auto serial = [&](const char* name) {
      return "{device: " + (dir_ / name).string() + ", baud: 115200}";
    };
    std::optional<LoadedConfig> loaded;
    EXPECT_EQ(load("modbus: {listen: 127.0.0.1:0}\n"
                   "metrics: {listen: 127.0.0.1:0}\n"
                   "console: {listen: 127.0.0.1:0}\n"
                   "buses:\n" +
                       test::copley_bus_item("a", serial("ttyA"), "",
                                             "      - {name: a1, address: 1, model: "
                                             "copley-amplifier, unit_id: 1" +
                                                 poll +
                                                 "}\n"
                                                 "      - {name: a2, address: 2, model: "
                                                 "copley-amplifier, unit_id: 2}\n") +
                       test::copley_bus_item("b", serial("ttyB"), "",
                                             "      - {name: b1, address: 1, model: "
                                             "copley-amplifier, unit_id: 3}\n"
                                             "      - {name: b2, address: 2, model: "
                                             "copley-amplifier, unit_id: 4}\n"),
                   &loaded),
              "");
    return std::make_shared<const LoadedConfig>(std::move(*loaded));
  }

  // Runs what a reload left ready to run (closing the console's old acceptor and the like).
  void settle() {
    io_.restart();
    io_.poll();
  }

  asio::io_context io_;
};

TEST_F(ReloadLeakTest, AHundredUnchangedReloadsLeaveNothingBehind) {
  Gateway g(io_, config());
  g.start();
  settle();
  for (int i = 0; i < 5; ++i) {  // every lazily made thing made once
    g.apply(config());
    settle();
  }
  const long before = g_live_allocations.load();
  std::vector<std::weak_ptr<const LoadedConfig>> applied;
  applied.reserve(100);
  for (int i = 0; i < 100; ++i) {
    auto next = config();
    applied.push_back(next);
    const auto summary = g.apply(std::move(next));
    ASSERT_EQ(summary, "2 bus(es) kept running, 0 started, 0 stopped");
    settle();
  }
  EXPECT_EQ(g.retired_generations(), 0u);
  std::size_t alive = 0;
  for (const auto& c : applied) alive += c.expired() ? 0 : 1;
  EXPECT_EQ(alive, 1u) << "configurations kept of the 100 applied (the one in force is one)";
  applied = {};
  RecordProperty("live_allocation_growth", std::to_string(g_live_allocations.load() - before));
  // A generation of this configuration is some thousands of allocations.
  EXPECT_LT(g_live_allocations.load() - before, 100) << "live allocations grew across 100 reloads";
}

// A site that changes a node's settings on every reload: its bus is reconfigured in place each
// time and keeps only the configurations it may still read (the first and the last few).
TEST_F(ReloadLeakTest, AHundredReloadsWithNodeChangesKeepABoundedFew) {
  Gateway g(io_, config());
  g.start();
  settle();
  std::vector<std::weak_ptr<const LoadedConfig>> applied;
  for (int i = 0; i < 100; ++i) {
    auto next = config(i % 2 ? ", poll: {fast: 200ms}" : ", poll: {fast: 300ms}");
    applied.push_back(next);
    const auto summary = g.apply(std::move(next));
    ASSERT_EQ(summary,
              "2 bus(es) kept running, 0 started, 0 stopped (1 of them with node changes applied "
              "in place)");
    settle();
  }
  std::size_t alive = 0;
  for (const auto& c : applied) alive += c.expired() ? 0 : 1;
  // The one in force and the two before it (bus a keeps its last three; the first is not here).
  EXPECT_LE(alive, 3u) << "configurations kept of the 100 applied";
  EXPECT_GE(alive, 1u);
}

TEST_F(ReloadLeakTest, ARequestUnderWayKeepsItsConfigurationUntilItEnds) {
  Gateway g(io_, config());
  g.start();
  auto first = config();
  const std::weak_ptr<const LoadedConfig> watched = first;
  g.apply(std::move(first));
  // As a Modbus request under way holds the handler it started with.
  auto held = g.handler(g.config().gateway.listener_name(0));
  g.apply(config());
  g.apply(config());
  settle();
  EXPECT_FALSE(watched.expired());
  EXPECT_EQ(g.retired_generations(), 1u);
  held.reset();
  // Freed without another reload.
  io_.restart();
  io_.run_for(1500ms);
  EXPECT_TRUE(watched.expired());
  EXPECT_EQ(g.retired_generations(), 0u);
}

}  // namespace
}  // namespace fieldgate
