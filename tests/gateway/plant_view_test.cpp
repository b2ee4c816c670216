// The console's plant JSON (GET /api/plant, the event stream's `plant`): its clock is Unix
// milliseconds as an integer, never in exponent notation.
#include <gtest/gtest.h>

#include <boost/asio/io_context.hpp>

#include <regex>

#include "config_file_test.hpp"
#include "gateway/console/plant_view.hpp"
#include "gateway/gateway.hpp"

namespace fieldgate {
namespace {

class PlantViewTest : public test::ConfigFileTest {};

TEST_F(PlantViewTest, TimeMsIsAnInteger) {
  std::optional<LoadedConfig> loaded;
  ASSERT_EQ(load("buses: []\n", &loaded), "");
  boost::asio::io_context io;
  Gateway g(io, std::make_shared<const LoadedConfig>(std::move(*loaded)));
  // 2026-12-08 02:51:17.879 UTC: as a double, Boost.JSON wrote 1.796698277879E12.
  const std::chrono::system_clock::time_point wall{std::chrono::milliseconds(1796698277879)};
  const std::string json = plant_json(g, std::chrono::steady_clock::now(), wall, nullptr);
  EXPECT_TRUE(json.starts_with(R"({"time_ms":1796698277879,)")) << json.substr(0, 80);
  EXPECT_TRUE(std::regex_search(json, std::regex(R"("time_ms":\d+,)"))) << json.substr(0, 80);
}

}  // namespace
}  // namespace fieldgate
