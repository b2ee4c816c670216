#include "mapping/model_options.hpp"

#include <gtest/gtest.h>

#include "mapping/model_loader.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

const ModelOptionSpecs& specs() {
  static const ModelOptionSpecs s{
      flag_option("confirm", "true", "confirm every command"),
      integer_option("line_limit", "12", 2, 64, "longest line"),
      integer_option("jumper", "75", {"25", "50", "75", "100"}, "acceleration jumper"),
      number_option("firmware", "1.09", 0.01, 99, "firmware version"),
      duration_option("settle", "300ms", 0us, std::chrono::microseconds(1h), "settle time"),
      choice_option("mode", "warning", {"warning", "rts"}, "overflow mode"),
      text_option("travel", "", "per-axis travel"),
  };
  return s;
}

ModelPtr model_with(const std::string& options, Diagnostics& d) {
  return load_model_text("model: m\nfamily: f\noptions: {" + options + "}\n", "m.yaml", d);
}

TEST(ModelOptions, DefaultsWhenNotGiven) {
  Diagnostics d;
  const auto m = model_with("", d);
  ASSERT_TRUE(m && d.ok()) << d.to_text();
  const auto v = check_model_options(*m, "f", specs(), d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  EXPECT_TRUE(v.flag("confirm"));
  EXPECT_EQ(v.integer("line_limit"), 12);
  EXPECT_EQ(v.integer("jumper"), 75);
  EXPECT_DOUBLE_EQ(v.number("firmware"), 1.09);
  EXPECT_EQ(v.duration("settle"), 300ms);
  EXPECT_EQ(v.text("mode"), "warning");
  EXPECT_FALSE(v.given("travel"));
  EXPECT_THROW((void)v.flag("undeclared"), std::logic_error);
}

TEST(ModelOptions, EveryFlagWordTheGatewayConfigAccepts) {
  for (const auto& [word, value] : std::vector<std::pair<std::string, bool>>{{"true", true},
                                                                             {"yes", true},
                                                                             {"on", true},
                                                                             {"false", false},
                                                                             {"no", false},
                                                                             {"off", false}}) {
    Diagnostics d;
    const auto m = model_with("confirm: " + word, d);
    ASSERT_TRUE(m) << d.to_text();
    const auto v = check_model_options(*m, "f", specs(), d);
    EXPECT_TRUE(d.ok()) << word << ": " << d.to_text();
    EXPECT_EQ(v.flag("confirm"), value) << word;
    EXPECT_TRUE(v.given("confirm"));
  }
}

TEST(ModelOptions, GivenValuesAreParsed) {
  Diagnostics d;
  const auto m = model_with(
      "line_limit: 20, jumper: 100, firmware: 1.15, settle: 2s, mode: rts, travel: '1,2,3'", d);
  ASSERT_TRUE(m) << d.to_text();
  const auto v = check_model_options(*m, "f", specs(), d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  EXPECT_EQ(v.integer("line_limit"), 20);
  EXPECT_EQ(v.integer("jumper"), 100);
  EXPECT_DOUBLE_EQ(v.number("firmware"), 1.15);
  EXPECT_EQ(v.duration("settle"), 2s);
  EXPECT_EQ(v.text("mode"), "rts");
  EXPECT_EQ(v.text("travel"), "1,2,3");
}

TEST(ModelOptions, EachBadValueIsReportedAtItsOwnPlace) {
  Diagnostics d;
  const auto m = model_with(
      "confirm: maybe, line_limit: 65, jumper: 60, firmware: new, settle: 0.05, mode: loud, "
      "speed: 3",
      d);
  ASSERT_TRUE(m) << d.to_text();
  const auto v = check_model_options(*m, "f", specs(), d);
  const std::string text = d.to_text();
  for (const char* expected : {
           "m.yaml:3:11: error: model m: option confirm: expected true or false, found 'maybe'",
           "m.yaml:3:27: error: model m: option line_limit: expected an integer 2..64, found '65'",
           "m.yaml:3:43: error: model m: option jumper: expected 25, 50, 75 or 100, found '60'",
           "m.yaml:3:55: error: model m: option firmware: expected a number 0.01..99, found 'new'",
           // a bare number is not a duration: 0.05 would otherwise silently mean 50 µs
           "m.yaml:3:70: error: model m: option settle: expected a duration 0s..3600s (with its "
           "unit: us, ms, s), found '0.05'",
           "m.yaml:3:84: error: model m: option mode: expected warning or rts, found 'loud'",
           "m.yaml:3:96: error: model m: unknown f option 'speed' (known: confirm, line_limit, "
           "jumper, firmware, settle, mode and travel; `fieldgate models --options f` describes "
           "them)",
       })
    EXPECT_NE(text.find(expected), std::string::npos) << expected << "\n" << text;
  EXPECT_EQ(d.errors().size(), 7u) << text;
  // A bad value reads as the default: the model never runs, but nothing reads garbage.
  EXPECT_TRUE(v.flag("confirm"));
  EXPECT_EQ(v.integer("line_limit"), 12);
}

TEST(ModelOptions, RequiredOptionAndFamilyWithoutOptions) {
  Diagnostics d;
  const auto m = model_with("variant: c10", d);
  ASSERT_TRUE(m) << d.to_text();
  const ModelOptionSpecs need{required(choice_option("variant", "", {"c10", "c142"}, "card"))};
  (void)check_model_options(*m, "t", need, d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  const auto empty = model_with("", d);
  (void)check_model_options(*empty, "t", need, d);
  ASSERT_EQ(d.errors().size(), 1u);
  EXPECT_NE(d.errors()[0].message.find("option variant is required (c10 or c142)"),
            std::string::npos)
      << d.to_text();
  Diagnostics none;
  (void)check_model_options(*m, "w", {}, none, "set it per node");
  ASSERT_EQ(none.errors().size(), 1u);
  EXPECT_EQ(none.errors()[0].message,
            "model m: option 'variant': the w family has no model options (set it per node)");
}

TEST(ModelOptions, DescribedAsATable) {
  const std::string table = describe_model_options("f", specs());
  EXPECT_NE(table.find("| settle | duration | 300ms | a duration 0s..3600s"), std::string::npos)
      << table;
  EXPECT_NE(table.find("| travel | text | - | text | per-axis travel |"), std::string::npos)
      << table;
  EXPECT_EQ(describe_model_options("w", {}), "The w family has no model options.\n");
}

}  // namespace
}  // namespace fieldgate
