// FleetView, the decoder behind sparkplug-spy and the console's Fleet tab: births name the
// metrics (and their aliases), data by alias is named from them, deaths end what they should
// and no more.
#include <gtest/gtest.h>

#include <string>

#include "gateway/sparkplug/fleet_view.hpp"
#include "gateway/sparkplug/payload.hpp"

namespace fieldgate::sparkplug {
namespace {

std::string nbirth(uint64_t bd_seq) {
  Payload p = make_payload(1000, 0);
  add_metric(p, "bdSeq", DataType::uint64, {false, static_cast<int64_t>(bd_seq), ""}, 1000);
  return encode(p);
}

std::string dbirth(uint64_t seq) {
  Payload p = make_payload(1000, seq);
  add_metric(p, "motor_position", DataType::int32, {false, -5, ""}, 1000);
  p.mutable_metrics(0)->set_alias(7);
  add_metric(p, "name", DataType::string, {false, 0, "x axis"}, 1000);
  return encode(p);
}

std::string ddata_by_alias(uint64_t seq, int32_t position) {
  Payload p = make_payload(2000, seq);
  add_metric(p, "motor_position", DataType::int32, {false, position, ""}, 2000);
  p.mutable_metrics(0)->clear_name();
  p.mutable_metrics(0)->set_alias(7);
  return encode(p);
}

std::string ndeath(uint64_t bd_seq) {
  Payload p = make_payload(3000, std::nullopt);
  add_metric(p, "bdSeq", DataType::uint64, {false, static_cast<int64_t>(bd_seq), ""}, 3000);
  return encode(p);
}

TEST(FleetView, BirthsNameWhatDataSendsByAlias) {
  FleetView v;
  EXPECT_EQ(v.take("spBv1.0/plant/NBIRTH/gw1", nbirth(4), 1),
            "NBIRTH gw1 seq 0\n  bdSeq = 4 (UInt64)\n");
  EXPECT_EQ(v.take("spBv1.0/plant/DBIRTH/gw1/axis_3", dbirth(1), 2),
            "DBIRTH gw1/axis_3 seq 1\n  motor_position = -5 (Int32)\n  name = x axis (String)\n");
  EXPECT_EQ(v.take("spBv1.0/plant/DDATA/gw1/axis_3", ddata_by_alias(2, 1234), 3),
            "DDATA gw1/axis_3 seq 2\n  motor_position = 1234 (Int32)\n");
  const auto& node = v.edge_nodes().at("gw1");
  EXPECT_TRUE(node.born);
  EXPECT_EQ(node.bd_seq, 4u);
  const auto& device = node.devices.at("axis_3");
  EXPECT_TRUE(device.born);
  EXPECT_EQ(device.metrics.at("motor_position").value, "1234");
  EXPECT_EQ(node.seq_gaps, 0u);
}

TEST(FleetView, ASeqGapIsMarked) {
  FleetView v;
  v.take("spBv1.0/plant/NBIRTH/gw1", nbirth(0), 1);
  v.take("spBv1.0/plant/DBIRTH/gw1/a", dbirth(1), 2);
  const std::string text = v.take("spBv1.0/plant/DDATA/gw1/a", ddata_by_alias(5, 1), 3);
  EXPECT_EQ(text.substr(0, text.find('\n')), "DDATA gw1/a seq 5 (expected seq 2)");
  EXPECT_EQ(v.edge_nodes().at("gw1").seq_gaps, 1u);
}

TEST(FleetView, AnNdeathOfAnOlderSessionIsIgnored) {
  FleetView v;
  v.take("spBv1.0/plant/NBIRTH/gw1", nbirth(3), 1);
  v.take("spBv1.0/plant/DBIRTH/gw1/a", dbirth(1), 2);
  // The will of the session before, delivered late by the broker.
  EXPECT_NE(v.take("spBv1.0/plant/NDEATH/gw1", ndeath(2), 3).find("ignored"), std::string::npos);
  EXPECT_TRUE(v.edge_nodes().at("gw1").born);
  EXPECT_EQ(v.take("spBv1.0/plant/NDEATH/gw1", ndeath(3), 4),
            "NDEATH gw1 bdSeq 3: the edge node and its devices are dead\n");
  EXPECT_FALSE(v.edge_nodes().at("gw1").born);
  EXPECT_FALSE(v.edge_nodes().at("gw1").devices.at("a").born);
}

TEST(FleetView, GarbageIsCountedNotTaken) {
  FleetView v;
  EXPECT_NE(
      v.take("spBv1.0/plant/NBIRTH/gw1", "\xff\xff\xff", 1).find("not a Sparkplug B protobuf"),
      std::string::npos);
  EXPECT_NE(v.take("other/topic", "", 1).find("not a Sparkplug B topic"), std::string::npos);
  EXPECT_EQ(v.malformed(), 2u);
  EXPECT_FALSE(v.edge_nodes().count("gw1") && v.edge_nodes().at("gw1").born);
  EXPECT_EQ(v.take("spBv1.0/STATE/scada1", R"({"online":true})", 1),
            "STATE host scada1: {\"online\":true}\n");
  EXPECT_EQ(v.hosts().at("scada1"), R"({"online":true})");
}

}  // namespace
}  // namespace fieldgate::sparkplug
