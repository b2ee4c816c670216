// Gateway::apply with a bus that must be rebuilt (its timing or a node changed): the nodes that
// are themselves unchanged keep serving what the replaced bus read, with its age, until the new
// bus has been in touch with them; a node whose address changed starts afresh.
#include <gtest/gtest.h>

#include <boost/asio/io_context.hpp>

#include "config_file_test.hpp"
#include "gateway/gateway.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
namespace asio = boost::asio;
using modbus::ExceptionCode;
using modbus::RegisterTable;

class ReloadCarryOverTest : public test::ConfigFileTest {
 protected:
  // Two Copley amplifiers on a port that does not exist: the buses are built, never opened (the
  // io_context does not run), so every node stays starting.
  std::shared_ptr<const LoadedConfig> config(const std::string& timing,
                                             const std::string& y_address,
                                             const std::string& x_setpoints = "") {
    std::optional<LoadedConfig> loaded;
    EXPECT_EQ(load("buses:\n  - name: b\n    protocol: copley-ascii\n"
                   "    serial: {device: " +
                       (dir_ / "ttyNone").string() + ", baud: 115200}\n" + timing +
                       "    nodes:\n"
                       "      - {name: x, address: 0, model: copley-amplifier, unit_id: 1" +
                       x_setpoints +
                       "}\n"
                       "      - {name: y, address: " +
                       y_address + ", model: copley-amplifier, unit_id: 2}\n",
                   &loaded),
              "");
    return std::make_shared<const LoadedConfig>(std::move(*loaded));
  }

  // The first one-register point of unit 1's input registers.
  static const RegisterEntry& a_point(const LoadedConfig& c) {
    for (const auto& e :
         c.register_map.unit(1)->tables[static_cast<std::size_t>(Table::input_registers)])
      if (e.kind == RegisterEntry::Kind::point && e.count == 1) return e;
    ADD_FAILURE() << "no one-register point";
    static const RegisterEntry none;
    return none;
  }

  modbus::ReadRegistersResult read(Gateway& g, uint8_t unit, uint16_t address) {
    return g.handler(g.config().gateway.listener_name(0))
        ->read_registers(unit, RegisterTable::input_registers, address, 1);
  }

  // Values as the replaced bus would have left them: x and y read 1 s ago (within the 2 s a
  // fast point may be old before it is stale, docs/register-map.md).
  static void polled(Gateway& g, const RegisterEntry& point) {
    auto images = g.buses().at(0)->node_images();
    const auto then = std::chrono::steady_clock::now() - 1s;
    for (std::size_t n = 0; n < images.size(); ++n) {
      for (auto& v : images[n]->points) v = {0, then, true};
      images[n]->points.at(static_cast<std::size_t>(point.index)).value =
          static_cast<int64_t>(1000 + n);
      images[n]->counters.last_good = then;
      images[n]->counters.ever_good = true;
    }
  }

  asio::io_context io_;
};

// Found by the test below: the serial bus marked its polled points after moving its poll items
// into the plan, so the data age of every serial node read 0 (fresh) however old its values.
TEST_F(ReloadCarryOverTest, ASerialNodesDataAgeIsTheAgeOfItsOldestPolledValue) {
  Gateway g(io_, config("", "3"));
  polled(g, a_point(g.config()));
  const auto age =
      g.image().diagnostic(0, DiagnosticField::data_age_ms, std::chrono::steady_clock::now());
  EXPECT_GE(age, 1000);
  EXPECT_LT(age, 0xffffffff);
  auto& image = *g.buses().at(0)->node_images().at(0);
  ASSERT_EQ(image.polled.size(), image.points.size());
  for (std::size_t p = 0; p < image.points.size(); ++p)
    if (image.polled[p]) {
      image.points[p].valid = false;
      break;
    }
  EXPECT_EQ(g.image().diagnostic(0, DiagnosticField::data_age_ms, std::chrono::steady_clock::now()),
            0xffffffff)
      << "a polled point never read";
}

TEST_F(ReloadCarryOverTest, AnUnchangedNodeKeepsServingWhileItsBusIsRebuilt) {
  Gateway g(io_, config("", "3"));
  const RegisterEntry point = a_point(g.config());
  polled(g, point);
  // Starting and never carried over: nothing is served.
  auto before = read(g, 1, point.address);
  ASSERT_FALSE(before.ok());
  EXPECT_EQ(before.exception(), ExceptionCode::gateway_target_failed);

  // The bus's timing changed and node y moved: the bus is rebuilt.
  const auto old_bus = g.buses().at(0);
  g.apply(config("    timing: {reply_timeout: 200ms}\n", "5"));
  ASSERT_NE(g.buses().at(0), old_bus);

  auto x = read(g, 1, point.address);
  ASSERT_TRUE(x.ok()) << static_cast<int>(x.exception());
  EXPECT_EQ(x.values().at(0), 1000);
  EXPECT_EQ(g.image().node(0).state, NodeState::starting) << "still not in touch";
  const auto age =
      g.image().diagnostic(0, DiagnosticField::data_age_ms, std::chrono::steady_clock::now());
  EXPECT_GE(age, 1000) << "served with its age";
  EXPECT_LT(age, 0xffffffff) << "every value was carried over";

  auto y = read(g, 2, point.address);
  ASSERT_FALSE(y.ok()) << "y is at another address now: another device";
  EXPECT_EQ(y.exception(), ExceptionCode::gateway_target_failed);
}

TEST_F(ReloadCarryOverTest, ANodeFoundOfflineByTheNewBusServesNothing) {
  Gateway g(io_, config("", "3"));
  const RegisterEntry point = a_point(g.config());
  polled(g, point);
  g.apply(config("    timing: {reply_timeout: 200ms}\n", "3"));
  ASSERT_TRUE(read(g, 1, point.address).ok());
  g.buses().at(0)->node_images().at(0)->state = NodeState::offline;
  auto x = read(g, 1, point.address);
  ASSERT_FALSE(x.ok());
  EXPECT_EQ(x.exception(), ExceptionCode::gateway_target_failed);
}

TEST_F(ReloadCarryOverTest, SetpointsTheSiteDidNotChangeKeepTheirValues) {
  Gateway g(io_, config("", "3"));
  const Model& model = *g.config().gateway.buses[0].nodes[0].model;
  ASSERT_FALSE(model.setpoints.empty());
  const std::string name = model.setpoints.front().name;
  for (auto& image : g.buses().at(0)->node_images()) image->setpoints.at(0) = 77;

  g.apply(config("    timing: {reply_timeout: 200ms}\n", "3"));
  EXPECT_EQ(g.image().node(0).setpoints.at(0), 77);
  EXPECT_EQ(g.image().node(1).setpoints.at(0), 77);

  // x's configured setpoints changed: it starts from them.
  g.apply(config("", "3", ", setpoints: {" + name + ": 5}"));
  EXPECT_EQ(g.image().node(0).setpoints.at(0), 5);
  EXPECT_EQ(g.image().node(1).setpoints.at(0), 77);
}

}  // namespace
}  // namespace fieldgate
