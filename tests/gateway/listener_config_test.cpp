#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "config_file_test.hpp"
#include "gateway/config/config_loader.hpp"
#include "text_checks.hpp"

// Several Modbus listeners, each with its own unit-ID space.
namespace fieldgate {
namespace {

namespace fs = std::filesystem;

class ListenerConfigTest : public test::ConfigFileTest {};

// Line 1 is models:; the listeners begin on line 2.
const std::string kListeners =
    "modbus: {listen: 127.0.0.1:1502}\n"
    "listeners:\n"
    "  - {name: line-a, listen: 127.0.0.1:1503, allow: [10.0.0.0/8], writes_enabled: false}\n"
    "  - name: line-b\n"
    "    listen: 127.0.0.1:1504\n"
    "    word_order: low_first\n";

std::string copley_bus(const std::string& name, const std::string& device, const std::string& extra,
                       const std::string& nodes) {
  return test::copley_bus_item(name, "{device: " + device + ", baud: 115200}", extra, nodes);
}

TEST_F(ListenerConfigTest, SameUnitIdOnTwoListeners) {
  std::optional<LoadedConfig> c;
  ASSERT_EQ(load(kListeners + "buses:\n" +
                     copley_bus("b1", "/dev/null", "    listener: line-a\n",
                                "      - {name: a1, address: 0, model: copley-amplifier, "
                                "unit_id: 1}\n"
                                "      - {name: d1, address: 2, model: copley-amplifier, "
                                "unit_id: 1, listener: default}\n") +
                     copley_bus("b2", "/dev/zero", "",
                                "      - {name: b1, address: 0, model: copley-amplifier, "
                                "unit_id: 1, listener: line-b}\n"),
                 &c),
            "");
  ASSERT_TRUE(c);
  const auto& g = c->gateway;
  ASSERT_EQ(g.listener_count(), 3u);
  EXPECT_EQ(g.listener_name(0), "default");
  EXPECT_EQ(g.listener_name(1), "line-a");
  EXPECT_EQ(g.listener_name(2), "line-b");
  EXPECT_EQ(g.listener_modbus(1).port, 1503);
  EXPECT_FALSE(g.listener_modbus(1).writes_enabled);
  EXPECT_TRUE(g.listener_modbus(0).writes_enabled);
  EXPECT_FALSE(g.listener_modbus(1).allow.empty());
  EXPECT_TRUE(g.listener_modbus(2).allow.empty());
  EXPECT_EQ(c->map_of(2).word_order(), WordOrder::low_first);
  EXPECT_EQ(c->map_of(0).word_order(), WordOrder::high_first);
  // The bus's listener applies to its nodes unless a node names its own.
  EXPECT_EQ(g.buses[0].nodes[0].listener, 1u);
  EXPECT_EQ(g.buses[0].nodes[1].listener, 0u);
  EXPECT_EQ(g.buses[1].nodes[0].listener, 2u);
  // Unit 1 names a different node (global node number) on each listener.
  ASSERT_TRUE(c->map_of(0).unit(1));
  ASSERT_TRUE(c->map_of(1).unit(1));
  ASSERT_TRUE(c->map_of(2).unit(1));
  EXPECT_EQ(c->map_of(1).unit(1)->node_name, "a1");
  EXPECT_EQ(c->map_of(1).unit(1)->node_index, 0);
  EXPECT_EQ(c->map_of(0).unit(1)->node_name, "d1");
  EXPECT_EQ(c->map_of(0).unit(1)->node_index, 1);
  EXPECT_EQ(c->map_of(2).unit(1)->node_name, "b1");
  EXPECT_EQ(c->map_of(2).unit(1)->node_index, 2);
  EXPECT_EQ(c->map_of(0).units().size(), 1u);
  EXPECT_EQ(&c->map_of(0), &c->register_map);
}

TEST_F(ListenerConfigTest, DuplicateUnitIdOnOneListenerNamesBoth) {
  const auto e = load(kListeners + "buses:\n" +
                      copley_bus("b1", "/dev/null", "    listener: line-a\n",
                                 "      - {name: x, address: 0, model: copley-amplifier, "
                                 "unit_id: 7}\n") +
                      copley_bus("b2", "/dev/zero", "",
                                 "      - {name: y, address: 0, model: copley-amplifier, "
                                 "unit_id: 7, listener: line-a}\n"));
  // x's unit_id is on line 14, column 65; y's on line 19.
  test::expect_contains(e, {"gw.yaml:19:65: error: node y: unit_id 7 is already used by node x (",
                            "gw.yaml:14:65) on listener line-a"});
}

TEST_F(ListenerConfigTest, UnknownListenerListsKnownOnes) {
  const auto e = load(kListeners + "buses:\n" +
                      copley_bus("b1", "/dev/null", "    listener: line-c\n",
                                 "      - {name: x, address: 0, model: copley-amplifier, "
                                 "unit_id: 7}\n"));
  test::expect_contains(e, {"gw.yaml:12:15: error: bus b1: unknown listener 'line-c' (listeners: "
                            "default, line-a, line-b)"});
}

TEST_F(ListenerConfigTest, ListenerErrors) {
  const std::string nodes =
      "buses:\n" + copley_bus("b1", "/dev/null", "",
                              "      - {name: x, address: 0, model: copley-amplifier, "
                              "unit_id: 7}\n");
  // Same endpoint as another listener, including the wildcard address.
  auto e =
      load("modbus: {listen: 0.0.0.0:1502}\nlisteners:\n  - {name: a, listen: 127.0.0.1:1502}\n" +
           nodes);
  test::expect_contains(
      e, {"gw.yaml:4:23: error: listener a: 127.0.0.1:1502 overlaps listener default "
          "(0.0.0.0:1502, "});
  // A name is required, unique and not "default"; listen is required.
  e = load(
      "listeners:\n  - {listen: 127.0.0.1:1503}\n  - {name: default, listen: "
      "127.0.0.1:1504}\n  - {name: a, listen: 127.0.0.1:1505}\n  - {name: a, listen: "
      "127.0.0.1:1506}\n  - {name: b}\n" +
      nodes);
  test::expect_contains(e,
                        {"listener: missing required key 'name'",
                         "listener default: listener name is already used (by the modbus: section)",
                         "gw.yaml:6:12: error: listener a: listener name is already used",
                         "listener b: missing required key 'listen'"});
  // Listener options are checked as modbus: ones are, under the listener's name.
  e = load("listeners:\n  - {name: a, listen: 127.0.0.1:1503, when_full: drop, max_clent: 3}\n" +
           nodes);
  test::expect_contains(e, {"listener a when_full: expected evict_idle or refuse, found 'drop'",
                            "listener a: unknown key 'max_clent'"});
  // The default listener has no name.
  e = load("modbus: {name: x}\n" + nodes);
  test::expect_contains(e, {"modbus: the default listener has no name"});
}

TEST_F(ListenerConfigTest, WithoutListenersEverythingIsOnTheDefault) {
  std::optional<LoadedConfig> c;
  ASSERT_EQ(load("buses:\n" + copley_bus("b1", "/dev/null", "",
                                         "      - {name: x, address: 0, model: copley-amplifier, "
                                         "unit_id: 7}\n"),
                 &c),
            "");
  ASSERT_TRUE(c);
  EXPECT_EQ(c->gateway.listener_count(), 1u);
  EXPECT_TRUE(c->listener_maps.empty());
  EXPECT_TRUE(c->register_map.unit(7));
}

// Admission keys: the connect rates (defaults, per listener), the metrics allow list, the
// console's cap on waiting connections per address.
TEST_F(ListenerConfigTest, AdmissionKeys) {
  const std::string nodes =
      "buses:\n" + copley_bus("b1", "/dev/null", "",
                              "      - {name: x, address: 0, model: copley-amplifier, "
                              "unit_id: 7}\n");
  std::optional<LoadedConfig> c;
  ASSERT_EQ(load("modbus: {listen: 127.0.0.1:1502}\n"
                 "listeners:\n"
                 "  - {name: a, listen: 127.0.0.1:1503, max_connects_per_second: 0,\n"
                 "     max_connects_per_second_per_address: 5}\n"
                 "metrics: {listen: 127.0.0.1:9502, allow: [10.0.0.0/8, \"fd00::/8\"]}\n"
                 "console: {listen: 127.0.0.1:9580, max_pending_per_address: 4}\n" +
                     nodes,
                 &c),
            "");
  ASSERT_TRUE(c);
  const auto& g = c->gateway;
  EXPECT_EQ(g.listener_modbus(0).max_connects_per_second, 200u);
  EXPECT_EQ(g.listener_modbus(0).max_connects_per_second_per_address, 40u);
  EXPECT_EQ(g.listener_modbus(1).max_connects_per_second, 0u);
  EXPECT_EQ(g.listener_modbus(1).max_connects_per_second_per_address, 5u);
  EXPECT_TRUE(g.metrics.allow.allows(asio::ip::make_address("10.1.2.3")));
  EXPECT_FALSE(g.metrics.allow.allows(asio::ip::make_address("127.0.0.1")));
  EXPECT_EQ(g.console.max_pending_per_address, 4u);

  ASSERT_EQ(load("metrics: {listen: 127.0.0.1:9502}\n" + nodes, &c), "");
  EXPECT_TRUE(c->gateway.metrics.allow.empty());
  EXPECT_EQ(c->gateway.console.max_pending_per_address, 16u);

  const auto e = load(
      "modbus: {max_connects_per_second: -1}\n"
      "metrics: {allow: [10.0.0.0/33]}\n"
      "console: {max_pending_per_address: many}\n" +
      nodes);
  test::expect_contains(e, {"modbus max_connects_per_second", "metrics allow: prefix length '33'",
                            "console max_pending_per_address"});
}

}  // namespace
}  // namespace fieldgate
