// A Techno C-series controller the family was not written for is a model file only: its
// differences (fitted_axes, arc_commands) are options. A made-up two-axis variant, written to a
// temporary directory, loads, is checked against its own axes and command set, and runs a
// transaction against the simulator in process.
#include <gtest/gtest.h>

#include <boost/asio/io_context.hpp>

#include <filesystem>
#include <fstream>

#include "drivers/techno_c/techno_family.hpp"
#include "mapping/model_loader.hpp"
#include "sim_transport.hpp"
#include "tests/harness/text_checks.hpp"

namespace fieldgate {
namespace {

namespace fs = std::filesystem;

constexpr const char* kVariantModel =
    "model: techno-xy2\n"
    "family: techno-c\n"
    "description: a made-up two-axis C-series controller without arc commands\n"
    "options:\n"
    "  variant: xy2\n"
    "  fitted_axes: 2\n"
    "  arc_commands: false\n"
    "  travel: 1000\n"
    "  timeout_margin: 150ms\n"
    "poll_classes: {fast: 100ms}\n"
    "points:\n"
    "  x: {type: int32, read: {request: P, field: 0, format: hex24}, poll: fast}\n"
    "  y: {type: int32, read: {request: P, field: 1, format: hex24}, poll: fast}\n"
    "setpoints:\n"
    "  speed: {type: uint16, min: 30, max: 10000, default: 100}\n"
    "actions:\n"
    "  stop: {code: 1, steps: [k]}\n";

class TechnoNewVariant : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fieldgate-techno-variant-" +
            std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "-" +
            std::to_string(reinterpret_cast<std::uintptr_t>(this)));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  ModelPtr load(const std::string& text, Diagnostics& d) {
    const fs::path file = dir_ / "techno-xy2.yaml";
    std::ofstream(file) << text;
    auto model = load_model_file(file.string(), d);
    if (model) family_.validate_model(*model, d);
    return model;
  }

  fs::path dir_;
  asio::io_context io_;
  TechnoFamily family_;
};

TEST_F(TechnoNewVariant, LoadsFromAModelFileAlone) {
  Diagnostics d;
  auto model = load(kVariantModel, d);
  ASSERT_TRUE(model);
  ASSERT_TRUE(d.ok()) << d.to_text();
  const auto profile = techno::read_profile(*model, d);
  EXPECT_EQ(profile.variant, "xy2");
  EXPECT_EQ(profile.fitted_axes, 2);
  EXPECT_FALSE(profile.arc_commands);
  EXPECT_EQ(profile.axes, 3);  // every fitted axis: X and Y
}

TEST_F(TechnoNewVariant, ItsAxesAndCommandSetAreChecked) {
  std::string text = kVariantModel;
  text.replace(text.find("  fitted_axes: 2\n"), 0, "  axes: 5\n");
  text += "  arc: {code: 2, steps: ['f-1']}\n";
  Diagnostics d;
  load(text, d);
  const std::string e = d.to_text();
  test::expect_contains(
      e, {"techno-xy2.yaml:6:3: error:", "option axes: '5' is not within the XY fitted axes",
          "variant xy2 has arc_commands: false"});
}

TEST_F(TechnoNewVariant, AnUnknownVariantMustSayHowItDiffers) {
  std::string text = kVariantModel;
  text.erase(text.find("  arc_commands: false\n"), std::string("  arc_commands: false\n").size());
  Diagnostics d;
  load(text, d);
  const std::string e = d.to_text();
  test::expect_contains(
      e, {"techno-xy2.yaml:5:3: error:", "another controller gives fitted_axes and arc_commands"});
}

TEST_F(TechnoNewVariant, RunsATransactionAgainstTheSimulator) {
  Diagnostics d;
  auto model = load(kVariantModel, d);
  ASSERT_TRUE(model && d.ok()) << d.to_text();
  sim::techno::ControllerOptions options;
  options.variant = sim::techno::Variant::c116;  // the simulator's closest: no arc commands
  options.axes = 0;                              // powered up: the axes are not defined yet
  sim::FaultInjection faults;
  sim::techno::Controller controller(options, sim::SimClock::now());
  sim::techno::TechnoExchange exchange(controller, {}, faults);
  test::SimTransport transport(io_, exchange);
  Link link(transport);
  const NodeAddress device{"0", 0, 0};
  family_.configure_node(device, *model);
  const Request position{"P", Request::Expect::values, NumberFormat::hex24};
  const LinkTiming timing{std::chrono::milliseconds(100), std::chrono::milliseconds(20)};
  const Reply r = test::run(io_, family_.transact(link, device, position, timing));
  ASSERT_EQ(r.status, Reply::Status::ok) << r.text;
  // The `4` of the powered-up controller was answered with the variant's axes definition, XY.
  EXPECT_EQ(controller.axes(), 3);
  EXPECT_NE(transport.all_written().find("@03\r"), std::string::npos) << transport.all_written();
}

}  // namespace
}  // namespace fieldgate
