// Sparkplug B edge node parts without a broker: configuration, topics, payloads, STATE, deadbands.
#include <gtest/gtest.h>

#include "gateway/sparkplug/metric_mapping.hpp"
#include "gateway/sparkplug/payload.hpp"
#include "gateway/sparkplug/primary_host_state.hpp"
#include "gateway/sparkplug/sparkplug_config.hpp"
#include "gateway/sparkplug/topic_namespace.hpp"

namespace fieldgate::sparkplug {
namespace {

struct Parsed {
  SparkplugConfig config;
  Diagnostics diagnostics;
};

Parsed parse(const std::string& yaml) {
  Parsed p;
  YamlReader reader("site.yaml", p.diagnostics);
  const auto root = reader.load_string(yaml);
  parse_sparkplug_config(reader, root["sparkplug"], p.config);
  return p;
}

TEST(SparkplugConfig, ParsesEveryKey) {
  const auto p = parse(
      "sparkplug:\n"
      "  broker: mqtt://broker.plant:1884\n"
      "  group_id: line3\n"
      "  edge_node_id: gw7\n"
      "  keepalive: 20s\n"
      "  reconnect: {min: 500ms, max: 1min}\n"
      "  deadbands: {int32: 10, uint16: 2}\n"
      "  commands_enabled: true\n"
      "  primary_host_id: scada\n");
  ASSERT_TRUE(p.diagnostics.ok()) << p.diagnostics.to_text();
  const auto& c = p.config;
  EXPECT_TRUE(c.enabled);
  EXPECT_EQ(c.host, "broker.plant");
  EXPECT_EQ(c.port, 1884);
  EXPECT_FALSE(c.tls);
  EXPECT_EQ(c.effective_client_id(), "fieldgate-line3-gw7");
  EXPECT_EQ(c.keepalive, std::chrono::seconds(20));
  EXPECT_EQ(c.reconnect_max, std::chrono::minutes(1));
  EXPECT_EQ(c.deadband(ValueType::int32), 10);
  EXPECT_EQ(c.deadband(ValueType::int16), 0);
  EXPECT_TRUE(c.commands_enabled);
  EXPECT_EQ(c.primary_host_id, "scada");
}

TEST(SparkplugConfig, CommandsAreOffByDefaultAndTlsSchemeSetsPort) {
  const auto p = parse("sparkplug: {broker: 'mqtts://10.0.0.5', group_id: g, edge_node_id: e}\n");
  ASSERT_TRUE(p.diagnostics.ok()) << p.diagnostics.to_text();
  EXPECT_FALSE(p.config.commands_enabled);
  EXPECT_TRUE(p.config.tls);
  EXPECT_EQ(p.config.port, 8883);
}

TEST(SparkplugConfig, ErrorsArePrecise) {
  const auto p = parse(
      "sparkplug:\n"
      "  group_id: 'a/b'\n"
      "  edge_node_id: gw\n"
      "  keepalive: 30\n"
      "  deadbands: {float: 1}\n"
      "  brokr: x\n");
  const std::string text = p.diagnostics.to_text();
  EXPECT_NE(text.find("site.yaml:2:13"), std::string::npos) << text;
  EXPECT_NE(text.find("without '+', '#' or '/'"), std::string::npos) << text;
  EXPECT_NE(text.find("site.yaml:4:14"), std::string::npos) << text;  // a duration needs a unit
  EXPECT_NE(text.find("unknown point type 'float'"), std::string::npos) << text;
  EXPECT_NE(text.find("brokr"), std::string::npos) << text;
}

TEST(SparkplugConfig, MissingIdsAndBadPortAreReported) {
  const auto p = parse("sparkplug: {broker: 'mqtt://h:99999'}\n");
  const std::string text = p.diagnostics.to_text();
  EXPECT_NE(text.find("group_id"), std::string::npos) << text;
  EXPECT_NE(text.find("edge_node_id"), std::string::npos) << text;
  EXPECT_NE(text.find("bad port"), std::string::npos) << text;
}

TEST(TopicNamespace, TopicsOfTheSpecification) {
  TopicNamespace t("plant", "gw1");
  EXPECT_EQ(t.node_topic(MessageType::nbirth), "spBv1.0/plant/NBIRTH/gw1");
  EXPECT_EQ(t.device_topic(MessageType::ddata, "amp3"), "spBv1.0/plant/DDATA/gw1/amp3");
  EXPECT_EQ(t.dcmd_filter(), "spBv1.0/plant/DCMD/gw1/+");
  EXPECT_EQ(TopicNamespace::state_topic("scada"), "spBv1.0/STATE/scada");
  const auto d = t.parse_command("spBv1.0/plant/DCMD/gw1/amp3");
  ASSERT_TRUE(d);
  EXPECT_EQ(d->type, MessageType::dcmd);
  EXPECT_EQ(d->device_id, "amp3");
  EXPECT_EQ(t.parse_command("spBv1.0/plant/NCMD/gw1")->type, MessageType::ncmd);
  EXPECT_FALSE(t.parse_command("spBv1.0/plant/DCMD/gw2/amp3"));
  EXPECT_FALSE(t.parse_command("spBv1.0/plant/DCMD/gw1/a/b"));
}

TEST(Payload, SignedValuesRoundTrip) {
  Payload p = make_payload(1, 7);
  add_metric(p, "pos", DataType::int32, {false, -1500, {}}, 1);
  add_metric(p, "small", DataType::int16, {false, -2, {}}, 1);
  add_metric(p, "gone", DataType::int32, {true, 0, {}}, 1);
  const auto back = decode(encode(p));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->seq(), 7u);
  EXPECT_EQ(integer_value(back->metrics(0)), -1500);
  EXPECT_EQ(integer_value(back->metrics(1)), -2);
  EXPECT_FALSE(integer_value(back->metrics(2)));
  EXPECT_FALSE(decode("\xff\xff\xff"));
}

TEST(PrimaryHostState, ParsesAndIgnoresOlderMessages) {
  const auto on = parse_host_state(R"({"online" : true, "timestamp": 1700000000123})");
  ASSERT_TRUE(on);
  EXPECT_TRUE(on->online);
  EXPECT_EQ(on->timestamp, 1700000000123u);
  EXPECT_FALSE(parse_host_state(R"({"online": true})"));
  EXPECT_FALSE(parse_host_state("online"));
  PrimaryHostTracker tracker;
  EXPECT_TRUE(tracker.update(*on));
  EXPECT_FALSE(tracker.update({false, 1}));  // a stale will
  EXPECT_TRUE(tracker.online());
  EXPECT_TRUE(tracker.update({false, 1700000000200}));
  EXPECT_FALSE(tracker.online());
}

TEST(MetricMapping, DeadbandOfThePointType) {
  DeviceMetric m;
  m.type = DataType::int32;
  m.deadband = 10;
  EXPECT_FALSE(changed(m, {false, 100, {}}, {false, 110, {}}));
  EXPECT_TRUE(changed(m, {false, 100, {}}, {false, 111, {}}));
  EXPECT_TRUE(changed(m, {false, 100, {}}, {true, 0, {}}));
  m.deadband = 0;
  EXPECT_TRUE(changed(m, {false, 100, {}}, {false, 101, {}}));
}

}  // namespace
}  // namespace fieldgate::sparkplug
