#pragma once

// What the in-process serial bus tests (tests/gateway/serial_bus_*_test.cpp) share: a scratch
// folder with a Copley position model and the gateway file of one bus "copley", the
// configuration loaded from it, and a SerialBus of that configuration on a FakeLine (an
// in-memory line at 115200 baud), running on the test's io_context.

#include <gtest/gtest.h>
#include <unistd.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <utility>

#include "fake_line.hpp"
#include "gateway/bus/serial_bus.hpp"
#include "gateway/config/config_loader.hpp"

namespace fieldgate::test {

class SerialBusFiles {
 public:
  // The folder fieldgate-<kind>-<pid>-<name>, with models/ in it; removed with this.
  SerialBusFiles(const std::string& kind, const std::string& name)
      : dir_(std::filesystem::temp_directory_path() /
             ("fieldgate-" + kind + "-" + std::to_string(::getpid()) + "-" + name)) {
    std::filesystem::create_directories(dir_ / "models");
  }
  // The folder named after the running test.
  explicit SerialBusFiles(const std::string& kind)
      : SerialBusFiles(kind, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  ~SerialBusFiles() { std::filesystem::remove_all(dir_); }
  SerialBusFiles(const SerialBusFiles&) = delete;
  SerialBusFiles& operator=(const SerialBusFiles&) = delete;

  // models/position.yaml: poll class fast every `fast`, the points position (g r0x32) and
  // target (s r0xca), then `more` (YAML lines).
  void write_model(const std::string& fast, const std::string& more = "") const {
    std::ofstream(dir_ / "models" / "position.yaml")
        << "model: position\nfamily: copley-ascii\npoll_classes: {fast: " << fast
        << "}\npoints:\n  position: {type: int32, read: g r0x32, poll: fast}\n"
           "  target: {type: int32, write: \"s r0xca {value}\"}\n"
        << more;
  }

  // gw.yaml with the bus's timing (a YAML line, indented by four spaces) and nodes (list items,
  // indented by six), loaded as the daemon loads it; nullptr (and a test failure) if invalid.
  std::shared_ptr<const LoadedConfig> load(const std::string& timing,
                                           const std::string& nodes) const {
    std::ofstream(dir_ / "gw.yaml") << "models: models\nbuses:\n  - name: copley\n"
                                       "    protocol: copley-ascii\n"
                                       "    serial: {device: /dev/null, baud: 115200}\n"
                                    << timing << "    nodes:\n"
                                    << nodes;
    Diagnostics d;
    auto loaded = load_gateway_config((dir_ / "gw.yaml").string(), d);
    EXPECT_TRUE(loaded) << d.to_text();
    if (!loaded) return nullptr;
    return std::make_shared<const LoadedConfig>(std::move(*loaded));
  }

  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
};

// An in-memory line at 115200 baud (10 bits a character).
inline std::unique_ptr<FakeLine> fake_serial_line(asio::io_context& io) {
  return std::make_unique<FakeLine>(io, "fake", 1e6 * 10 / 115200);
}

// The configuration's first bus on `line`, spawned on io.
inline std::shared_ptr<SerialBus> run_serial_bus(asio::io_context& io,
                                                 const std::shared_ptr<const LoadedConfig>& config,
                                                 std::unique_ptr<FakeLine> line,
                                                 SerialBus::NodeUpdated on_update = nullptr,
                                                 SerialBus::TimeSource now = {}) {
  auto bus = std::make_shared<SerialBus>(io.get_executor(), config, config->gateway.buses[0], 0,
                                         std::move(on_update), std::move(line), std::move(now));
  asio::co_spawn(
      io, [bus]() -> asio::awaitable<void> { co_await bus->run(); }, asio::detached);
  return bus;
}

}  // namespace fieldgate::test
