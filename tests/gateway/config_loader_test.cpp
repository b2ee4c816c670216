#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "gateway/config_loader.hpp"

namespace fieldgate {
namespace {

namespace fs = std::filesystem;

class ConfigLoaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fieldgate-config-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Loads a gateway file that uses the shipped models; returns the error text, "" if valid.
  std::string load(const std::string& yaml, std::optional<LoadedConfig>* out = nullptr) {
    const auto path = dir_ / "gw.yaml";
    std::ofstream(path) << "models: " FIELDGATE_SOURCE_DIR "/config/models\n" << yaml;
    Diagnostics d;
    auto loaded = load_gateway_config(path.string(), d);
    if (out) *out = std::move(loaded);
    return d.to_text();
  }

  static std::string bus(const std::string& nodes, const std::string& extra = "") {
    return "buses:\n  - name: b\n    protocol: copley-ascii\n    serial: {device: /dev/null, "
           "baud: 115200}\n" +
           extra + "    nodes:\n" + nodes;
  }

  fs::path dir_;
};

TEST_F(ConfigLoaderTest, ValidConfigLoads) {
  std::optional<LoadedConfig> c;
  EXPECT_EQ(load(bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n"
                     "      - {name: y, address: 3.b, model: copley-amplifier, unit_id: 2}\n"),
                 &c),
            "");
  ASSERT_TRUE(c);
  ASSERT_EQ(c->gateway.buses.size(), 1u);
  EXPECT_EQ(c->gateway.buses[0].nodes[1].address.text, "3.b");
  EXPECT_TRUE(c->register_map.unit(2));
}

TEST_F(ConfigLoaderTest, UnknownKeyWithLineAndColumn) {
  const auto e = load(bus("      - {name: x, adress: 0, model: copley-amplifier, unit_id: 1}\n"));
  EXPECT_NE(e.find("gw.yaml:7:19: error: node x: unknown key 'adress'"), std::string::npos) << e;
  EXPECT_NE(e.find("missing required key 'address'"), std::string::npos) << e;
}

TEST_F(ConfigLoaderTest, WrongType) {
  const auto e =
      load(bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: one}\n"));
  EXPECT_NE(e.find("gw.yaml:7:65: error: node x unit_id: expected an integer, found 'one'"),
            std::string::npos)
      << e;
}

TEST_F(ConfigLoaderTest, DuplicateUnitId) {
  const auto e =
      load(bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n"
               "      - {name: y, address: 3, model: copley-amplifier, unit_id: 1}\n"));
  EXPECT_NE(e.find("gw.yaml:8:65: error: node y: unit_id 1 is already used by node x"),
            std::string::npos)
      << e;
}

TEST_F(ConfigLoaderTest, DuplicateNodeAddress) {
  const auto e =
      load(bus("      - {name: x, address: 3, model: copley-amplifier, unit_id: 1}\n"
               "      - {name: y, address: 3, model: copley-amplifier, unit_id: 2}\n"));
  EXPECT_NE(e.find("gw.yaml:8:28: error: node y: address 3 is already used by node x on bus b"),
            std::string::npos)
      << e;
}

TEST_F(ConfigLoaderTest, AddressOutOfFamilyRange) {
  const auto e =
      load(bus("      - {name: x, address: 128, model: copley-amplifier, unit_id: 1}\n"));
  EXPECT_NE(e.find("gw.yaml:7:28: error: node x address: Copley node ID must be 0..127"),
            std::string::npos)
      << e;
}

TEST_F(ConfigLoaderTest, UnknownModelListsKnownOnes) {
  const auto e = load(bus("      - {name: x, address: 0, model: copley-amp, unit_id: 1}\n"));
  EXPECT_NE(e.find("unknown model 'copley-amp' (models found: "), std::string::npos) << e;
  EXPECT_NE(e.find("copley-amplifier"), std::string::npos) << e;
}

TEST_F(ConfigLoaderTest, UnknownProtocolListsFamilies) {
  const auto e = load(
      "buses:\n  - name: b\n    protocol: modbus-rtu\n    serial: {device: x}\n"
      "    nodes: []\n");
  EXPECT_NE(e.find("gw.yaml:4:15: error: bus b: unknown protocol 'modbus-rtu' (known: "
                   "copley-ascii"),
            std::string::npos)
      << e;
}

TEST_F(ConfigLoaderTest, UnitIdRange) {
  const auto e = load(bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: 0}\n"));
  EXPECT_NE(e.find("unit_id: 0 is out of range 1..247"), std::string::npos) << e;
}

TEST_F(ConfigLoaderTest, BadTiming) {
  const auto e = load(bus("      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n",
                          "    timing: {reply_timeout: soon, retries: 20}\n"));
  EXPECT_NE(e.find("reply_timeout: expected a duration such as 250ms or 2s, found 'soon'"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("retries: 20 is out of range 0..10"), std::string::npos) << e;
}

TEST_F(ConfigLoaderTest, SerialAndTcpAreExclusive) {
  const auto e = load(
      "buses:\n  - name: b\n    protocol: copley-ascii\n"
      "    nodes:\n      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n");
  EXPECT_NE(e.find("needs exactly one of 'serial' or 'tcp'"), std::string::npos) << e;
}

TEST_F(ConfigLoaderTest, SetpointOverrideChecked) {
  const auto e =
      load(bus("      - name: x\n        address: 0\n        model: copley-amplifier\n"
               "        unit_id: 1\n        setpoints: {enable_mode: 5, speed: 3}\n"));
  EXPECT_NE(e.find("setpoint enable_mode: 5 is out of range 21..31"), std::string::npos) << e;
  EXPECT_NE(e.find("has no setpoint 'speed'"), std::string::npos) << e;
}

TEST_F(ConfigLoaderTest, MissingFileIsAnError) {
  Diagnostics d;
  EXPECT_FALSE(load_gateway_config((dir_ / "nope.yaml").string(), d));
  EXPECT_NE(d.to_text().find("cannot open file"), std::string::npos);
}

TEST_F(ConfigLoaderTest, PollBudgetWarning) {
  std::optional<LoadedConfig> c;
  std::string nodes;
  for (int i = 0; i < 10; ++i)
    nodes += "      - {name: n" + std::to_string(i) + ", address: " + std::to_string(i) +
             ", model: copley-amplifier, unit_id: " + std::to_string(i + 1) + "}\n";
  const std::string yaml =
      "buses:\n  - name: slow\n    protocol: copley-ascii\n"
      "    serial: {device: /dev/null, baud: 9600}\n    nodes:\n" +
      nodes;
  EXPECT_EQ(load(yaml, &c), "");
  ASSERT_TRUE(c);
  ASSERT_EQ(c->gateway.warnings.size(), 1u);
  EXPECT_NE(c->gateway.warnings[0].find("bus slow: the configured polls need"), std::string::npos)
      << c->gateway.warnings[0];
}

TEST_F(ConfigLoaderTest, ShippedDemoConfigIsValid) {
  ::setenv("FIELDGATE_DEMO_DIR", "/tmp", 1);
  Diagnostics d;
  auto c = load_gateway_config(FIELDGATE_SOURCE_DIR "/config/demo.yaml", d);
  EXPECT_TRUE(c) << d.to_text();
}

}  // namespace
}  // namespace fieldgate
