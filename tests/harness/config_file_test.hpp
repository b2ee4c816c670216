#pragma once

// A gtest fixture for the config loader's tests: a scratch directory per test and a gateway file
// in it that uses the shipped models (line 1), loaded as the daemon loads it.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

#include "gateway/config/config_loader.hpp"

namespace fieldgate::test {

// One item of a gateway file's buses: list, bus `name` of the copley-ascii family on `serial` (a
// YAML flow map), with `extra` (the bus's own keys, indented by four) and `nodes` (list items,
// indented by six).
inline std::string copley_bus_item(const std::string& name, const std::string& serial,
                                   const std::string& extra, const std::string& nodes) {
  return "  - name: " + name + "\n    protocol: copley-ascii\n    serial: " + serial + "\n" +
         extra + "    nodes:\n" + nodes;
}

class ConfigFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           ("fieldgate-" + std::string(info->test_suite_name()) + "-" + std::to_string(::getpid()) +
            "-" + info->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // Writes "models: <the shipped models>" and then yaml to gw.yaml and loads it; returns the
  // error text, "" if valid, and the loaded config in *out.
  std::string load(const std::string& yaml, std::optional<LoadedConfig>* out = nullptr) {
    const auto path = dir_ / "gw.yaml";
    std::ofstream(path) << "models: " FIELDGATE_SOURCE_DIR "/config/models\n" << yaml;
    Diagnostics d;
    auto loaded = load_gateway_config(path.string(), d);
    EXPECT_EQ(loaded.has_value(), d.ok()) << d.to_text();
    if (out) *out = std::move(loaded);
    return d.to_text();
  }

  std::filesystem::path dir_;
};

}  // namespace fieldgate::test
