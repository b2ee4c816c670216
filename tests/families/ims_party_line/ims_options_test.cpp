// The family constants that are model options (pacing_step_rate, save_interval): listed with
// their defaults, checked at their place in the model file, and taking effect on the node a model
// is bound to.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

#include <chrono>

#include "drivers/ims_party_line/ims_family.hpp"
#include "mapping/model_loader.hpp"
#include "tests/families/ims_party_line/chain_transport.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

ModelPtr model_with(const std::string& options, Diagnostics& d) {
  return load_model_text(
      "model: m\nfamily: ims-party-line\npoll_classes: {fast: 100ms}\n"
      "options:\n" +
          options,
      "m.yaml", d);
}

NodeAddress unit(char name) {
  return {std::string(1, name), static_cast<unsigned char>(name), 0};
}

TEST(ImsOptions, ListedWithTheirDefaults) {
  ImsPartyLineFamily family;
  const std::string table = describe_model_options("ims-party-line", family.model_options());
  for (const char* text : {"pacing_step_rate", "10000", "save_interval", "60s"})
    EXPECT_NE(table.find(text), std::string::npos) << text << "\n" << table;
}

TEST(ImsOptions, BadValuesAreErrorsAtTheirPlace) {
  Diagnostics d;
  auto model = model_with("  pacing_step_rate: fast\n  save_interval: -5s\n", d);
  ASSERT_TRUE(model) << d.to_text();
  ImsPartyLineFamily family;
  family.validate_model(*model, d);
  const std::string e = d.to_text();
  EXPECT_NE(e.find("m.yaml:5:3: error:"), std::string::npos) << e;
  EXPECT_NE(e.find("pacing_step_rate"), std::string::npos) << e;
  EXPECT_NE(e.find("m.yaml:6:3: error:"), std::string::npos) << e;
  EXPECT_NE(e.find("save_interval"), std::string::npos) << e;
}

TEST(ImsOptions, DefaultsAreTheManualsFigures) {
  Diagnostics d;
  auto model = model_with("  firmware: \"1.09\"\n", d);
  ASSERT_TRUE(model) << d.to_text();
  ImsPartyLineFamily family;
  family.configure_node(unit('A'), *model);
  EXPECT_EQ(family.shadow().limits('A').fast_step_rate, ims::ChainShadow::kFastStepRate);
  EXPECT_EQ(family.shadow().limits('A').save_interval, ims::ChainShadow::kSaveInterval);
}

class ImsOptionsOnTheChain : public ::testing::Test {
 protected:
  ImsOptionsOnTheChain() {
    sim::ims::PartyLineOptions options;
    options.names = {'A', 'B'};
    transport_ = std::make_unique<test::ChainTransport>(io_, std::move(options));
    link_ = std::make_unique<Link>(*transport_);
  }
  void bind(char name, const std::string& options) {
    Diagnostics d;
    auto model = model_with(options, d);
    ASSERT_TRUE(model) << d.to_text();
    family_.validate_model(*model, d);
    ASSERT_TRUE(d.ok()) << d.to_text();
    models_.push_back(model);
    family_.configure_node(unit(name), *model);
  }
  Reply transact(char name, const char* command) {
    const Request request{command, Request::Expect::ack, NumberFormat::decimal};
    auto future = asio::co_spawn(io_, family_.transact(*link_, unit(name), request, timing_),
                                 asio::use_future);
    io_.restart();
    while (future.wait_for(0s) != std::future_status::ready) io_.run_one_for(10ms);
    return future.get();
  }

  asio::io_context io_;
  std::unique_ptr<test::ChainTransport> transport_;
  std::unique_ptr<Link> link_;
  ImsPartyLineFamily family_;
  std::vector<ModelPtr> models_;
  LinkTiming timing_{30ms, 5ms};
};

TEST_F(ImsOptionsOnTheChain, SaveIntervalSetsHowSoonASecondSaveGoesOut) {
  bind('A', "  save_interval: 60s\n");
  bind('B', "  save_interval: 0s\n");
  for (char name : {'A', 'B'}) ASSERT_EQ(transact(name, "S").status, Reply::Status::ok) << name;
  const Reply a = transact('A', "S");
  EXPECT_EQ(a.status, Reply::Status::device_error);
  EXPECT_EQ(a.device_code, static_cast<int64_t>(ims::Refusal::eeprom_rate));
  EXPECT_NE(a.text.find("option save_interval"), std::string::npos) << a.text;
  EXPECT_EQ(transact('B', "S").status, Reply::Status::ok);
}

TEST_F(ImsOptionsOnTheChain, PacingStepRateSetsWhenTheChainIsPacedByEchoes) {
  bind('A', "  pacing_step_rate: 5000\n");
  bind('B', "  pacing_step_rate: 20000\n");
  const auto move_at_8000 = [&](char unit) {
    ASSERT_EQ(transact(unit, "V8000").status, Reply::Status::ok);
    ASSERT_EQ(transact(unit, "+100000").status, Reply::Status::ok);
  };
  // One line to the unit, on a line whose writes were cleared before it.
  const auto line_to = [&](char unit) {
    transport_->clear_writes();
    ASSERT_EQ(transact(unit, "V1000").status, Reply::Status::ok);
  };
  // B at 8000 steps/s is below its own threshold: lines go out whole.
  ASSERT_NO_FATAL_FAILURE(move_at_8000('B'));
  EXPECT_FALSE(family_.shadow().fast());
  ASSERT_NO_FATAL_FAILURE(line_to('A'));
  EXPECT_EQ(transport_->writes().size(), 1u);
  // A at 8000 steps/s is above its threshold of 5000: every line is paced by its echo.
  ASSERT_NO_FATAL_FAILURE(move_at_8000('A'));
  EXPECT_TRUE(family_.shadow().fast());
  ASSERT_NO_FATAL_FAILURE(line_to('B'));
  EXPECT_GT(transport_->writes().size(), 1u);
}

}  // namespace
}  // namespace fieldgate
