// Careless-operator checks: duplicate keys, durations without a unit, odd baud rates.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "config_file_test.hpp"
#include "gateway/config/config_loader.hpp"
#include "mapping/model_loader.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate {
namespace {

namespace fs = std::filesystem;

class ConfigHardening : public test::ConfigFileTest {
 protected:
  static std::string bus(const std::string& serial, const std::string& timing = "") {
    return "buses:\n" + test::copley_bus_item(
                            "b", serial, timing,
                            "      - {name: x, address: 0, model: copley-amplifier, unit_id: 1}\n");
  }
  static std::string serial(const std::string& baud) {
    return "{device: /dev/null, baud: " + baud + "}";
  }
};

TEST_F(ConfigHardening, TheBaseConfigIsValid) {
  EXPECT_EQ(load(bus(serial("115200"), "    timing: {reply_timeout: 50ms}\n")), "");
}

TEST_F(ConfigHardening, DuplicateKeyInAFlowMappingIsRejectedAtTheSecond) {
  const auto e = load(
      "buses:\n  - name: b\n    protocol: copley-ascii\n    serial: {device: /dev/null}\n"
      "    nodes:\n      - {name: x, address: 0, model: copley-amplifier, unit_id: 1, "
      "unit_id: 9}\n");
  EXPECT_NE(e.find("gw.yaml:7:68: error: 'unit_id' is defined twice in this mapping (first at "
                   "line 7, column 56)"),
            std::string::npos)
      << e;
}

TEST_F(ConfigHardening, DuplicateBlockKeyIsRejected) {
  const auto e = load(
      "modbus:\n  listen: 127.0.0.1:1502\n  max_clients: 4\n"
      "  listen: 0.0.0.0:502\n" +
      bus(serial("9600")));
  EXPECT_NE(e.find("gw.yaml:5:3: error: 'listen' is defined twice"), std::string::npos) << e;
  // The same key in different mappings is fine.
  EXPECT_EQ(load("modbus: {listen: 127.0.0.1:1502}\nmetrics: {listen: 127.0.0.1:9502}\n" +
                 bus(serial("9600"))),
            "");
}

TEST_F(ConfigHardening, DuplicateTopLevelKeyIsRejected) {
  const auto e = load(bus(serial("9600")) + bus(serial("9600")));
  EXPECT_NE(e.find("gw.yaml:8:1: error: 'buses' is defined twice"), std::string::npos) << e;
}

TEST_F(ConfigHardening, DuplicateKeyInAModelIsRejectedWithItsFile) {
  const auto models = dir_ / "models";
  fs::create_directories(models);
  std::ofstream(models / "m.yaml")
      << "model: m\nfamily: copley-ascii\npoll_classes: {fast: 100ms}\npoints:\n"
         "  p: {type: int32, read: g r0x17, poll: fast, units: counts, units: steps}\n";
  Diagnostics d;
  ModelLibrary library;
  library.load_directory(models.string(), d);
  EXPECT_NE(d.to_text().find("m.yaml:5:62: error: 'units' is defined twice"), std::string::npos)
      << d.to_text();
}

TEST_F(ConfigHardening, AliasesAreNotExpandedByTheCheck) {
  // A billion-laughs document: the duplicate-key walk follows events, not expanded nodes.
  Diagnostics d;
  YamlReader reader("laughs.yaml", d);
  std::string text = "a: &a [x, x, x, x, x, x, x, x, x, x]\n";
  for (char c = 'b'; c <= 'z'; ++c) {
    text += std::string(1, c) + ": &" + c + " [";
    for (int i = 0; i < 10; ++i) text += std::string(i ? ", *" : "*") + char(c - 1);
    text += "]\n";
  }
  reader.load_string(text);
  EXPECT_TRUE(d.ok()) << d.to_text();
}

TEST_F(ConfigHardening, MalformedTextFoundByTheFuzzerEndsWithAnError) {
  // yaml-cpp 0.7 reported documents forever on this text; the duplicate-key walk hung in it.
  std::ifstream in(FIELDGATE_SOURCE_DIR "/fuzz/corpus/config/regression-yaml-cpp-endless-documents",
                   std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(text.size(), 1u);
  Diagnostics d;
  EXPECT_FALSE(load_model_text(text.substr(1), "found.yaml", d));
  EXPECT_FALSE(d.ok());
}

TEST_F(ConfigHardening, DurationWithoutAUnitIsRejectedAndNamesTheFix) {
  const auto fraction = load(bus(serial("9600"), "    timing: {reply_timeout: 0.05}\n"));
  EXPECT_NE(fraction.find("gw.yaml:6:29: error: bus b timing reply_timeout: '0.05' has no unit; "
                          "write it with one, such as 0.05ms or 0.05s"),
            std::string::npos)
      << fraction;
  const auto whole = load(bus(serial("9600"), "    timing: {probe_interval: 2}\n"));
  EXPECT_NE(whole.find("probe_interval: '2' has no unit"), std::string::npos) << whole;
  const auto modbus = load("modbus: {idle_timeout: 300}\n" + bus(serial("9600")));
  EXPECT_NE(modbus.find("modbus idle_timeout: '300' has no unit"), std::string::npos) << modbus;
  EXPECT_EQ(load(bus(serial("9600"), "    timing: {reply_timeout: 0.05s, byte_timeout: 500us}\n")),
            "");
}

TEST_F(ConfigHardening, NonStandardBaudNeedsToBeAllowed) {
  for (const char* odd : {"11520", "9601", "250000"}) {
    const auto e = load(bus(serial(odd)));
    EXPECT_NE(e.find(std::string("bus b serial baud: ") + odd +
                     " is not a standard rate (such as 9600, 19200, 38400, 57600 or 115200); "
                     "if the adapter really supports it, add allow_nonstandard_baud: true"),
              std::string::npos)
        << e;
  }
  EXPECT_EQ(load(bus("{device: /dev/null, baud: 250000, allow_nonstandard_baud: true}")), "");
  EXPECT_NE(load(bus("{device: /dev/null, baud: 250000, allow_nonstandard_baud: false}"))
                .find("not a standard rate"),
            std::string::npos);
  for (const char* standard : {"1200", "9600", "19200", "38400", "57600", "115200", "921600"})
    EXPECT_EQ(load(bus(serial(standard))), "") << standard;
}

TEST_F(ConfigHardening, WhenFullAndPerAddressLimitAreChecked) {
  EXPECT_EQ(load("modbus: {when_full: refuse, max_clients_per_address: 2}\n" + bus(serial("9600"))),
            "");
  EXPECT_NE(load("modbus: {when_full: wait}\n" + bus(serial("9600")))
                .find("modbus when_full: expected evict_idle or refuse, found 'wait'"),
            std::string::npos);
}

TEST_F(ConfigHardening, ShippedConfigsLoad) {
  // The example and demo configs use units on every duration and standard rates.
  Diagnostics d;
  setenv("FIELDGATE_DEMO_DIR", "/dev", 0);
  load_gateway_config(FIELDGATE_SOURCE_DIR "/config/demo.yaml", d);
  EXPECT_TRUE(d.ok()) << d.to_text();
}

}  // namespace
}  // namespace fieldgate
