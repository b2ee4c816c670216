// The shipped techno-* models load and pass the family's checks; models that would let a Modbus
// write reach the controller with a value count or range it refuses are rejected at load.
#include <gtest/gtest.h>

#include "drivers/techno_c/techno_family.hpp"
#include "mapping/model_loader.hpp"
#include "tests/harness/text_checks.hpp"

namespace fieldgate {
namespace {

ModelPtr load(const std::string& text, Diagnostics& d) {
  return load_model_text(text, "test.yaml", d);
}

std::string errors_of(const std::string& text) {
  Diagnostics d;
  auto model = load(text, d);
  if (!d.ok()) return "LOAD: " + d.to_text();
  TechnoFamily family;
  family.validate_model(*model, d);
  return d.to_text();
}

// A small C142 model; `extra` adds to its points, setpoints or actions.
std::string model(const std::string& options, const std::string& points,
                  const std::string& setpoints, const std::string& actions) {
  return "model: m\nfamily: techno-c\noptions: {" + options +
         "}\npoll_classes: {fast: 100ms}\npoints:\n"
         "  x: {type: int32, read: {request: P, field: 0, format: hex24}, poll: fast}\n" +
         points + "setpoints:\n  speed: {type: uint16, min: 30, max: 10000, default: 100}\n" +
         "  d: {type: int32, min: -8000000, max: 8000000}\n" + setpoints + "actions:\n" + actions;
}

std::string with_action(const std::string& step, const std::string& options = "variant: c142") {
  return errors_of(
      model(options, "", "", "  go:\n    code: 1\n    steps:\n      - " + step + "\n"));
}

// The errors of a model with the given extra points (and options) and one plain action.
std::string with_points(const std::string& points, const std::string& options = "variant: c142") {
  return errors_of(model(options, points, "", "  k: {code: 1, steps: [k]}\n"));
}

std::string with_options(const std::string& options) {
  return with_points("", options);
}

TEST(TechnoModels, ShippedModelsAreValid) {
  for (const char* name : {"techno-c142", "techno-c116", "techno-c10", "techno-it116g"}) {
    Diagnostics d;
    auto m =
        load_model_file(std::string(FIELDGATE_SOURCE_DIR) + "/config/models/" + name + ".yaml", d);
    ASSERT_TRUE(m) << name;
    ASSERT_TRUE(d.ok()) << d.to_text();
    TechnoFamily family;
    family.validate_model(*m, d);
    EXPECT_TRUE(d.ok()) << name << ":\n" << d.to_text();
    EXPECT_EQ(m->family, "techno-c");
  }
}

TEST(TechnoModels, ShippedModelsReadOptions) {
  Diagnostics d;
  auto m =
      load_model_file(std::string(FIELDGATE_SOURCE_DIR) + "/config/models/techno-c142.yaml", d);
  ASSERT_TRUE(m);
  const auto p = techno::read_profile(*m, d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  EXPECT_EQ(p.variant, "c142");
  EXPECT_EQ(p.axes, 7);
  EXPECT_EQ(p.acceleration, 75000);
  EXPECT_FALSE(p.init_on_connect);
  ASSERT_TRUE(p.steps_per_unit);
  EXPECT_EQ((*p.steps_per_unit)[2], 100);
  auto it =
      load_model_file(std::string(FIELDGATE_SOURCE_DIR) + "/config/models/techno-it116g.yaml", d);
  ASSERT_TRUE(it);
  const auto q = techno::read_profile(*it, d);
  EXPECT_EQ(q.axes, 1);
  EXPECT_EQ(q.acceleration, 25000);  // the IT116G's DIP default
}

TEST(TechnoModels, ConfirmAfterIsParsedOnSendSteps) {
  Diagnostics d;
  auto m = load(model("variant: c142", "", "",
                      "  go:\n    code: 1\n    steps:\n"
                      "      - {send: 'A{d},{speed},0,30,0,30,0,30', confirm_after: 250ms}\n"),
                d);
  ASSERT_TRUE(m) << d.to_text();
  ASSERT_TRUE(d.ok()) << d.to_text();
  ASSERT_EQ(m->actions[0].steps.size(), 1u);
  EXPECT_EQ(m->actions[0].steps[0].confirm_after, std::chrono::milliseconds(250));
}

TEST(TechnoModels, ConfirmAfterMisuseIsALoadError) {
  Diagnostics d;
  load(model("variant: c142", "", "",
             "  a:\n    code: 1\n    steps:\n      - {delay: 1s, confirm_after: 1s}\n"
             "  b:\n    code: 2\n    steps:\n      - {send: '<stop>', urgent: true, confirm_after: "
             "1s}\n"
             "  c:\n    code: 3\n    steps:\n      - {send: k, confirm_after: 1s}\n"
             "      - {send: k, confirm_after: 1s}\n"),
       d);
  const std::string text = d.to_text();
  EXPECT_NE(text.find("confirm_after belongs to a 'send' step"), std::string::npos) << text;
  EXPECT_NE(text.find("urgent step does not wait"), std::string::npos) << text;
  EXPECT_NE(text.find("only one step may carry confirm_after"), std::string::npos) << text;
}

TEST(TechnoModels, MoveValueCountMustFitTheAxes) {
  EXPECT_EQ(with_action("'A{d},{speed},{d},{speed},{d},{speed},0,{speed}'"), "");
  const auto e = with_action("'A{d},{speed}'");
  EXPECT_NE(e.find("needs 8 value(s)"), std::string::npos) << e;
  EXPECT_EQ(with_action("'a{d},{speed}'", "variant: it116g"), "");
  EXPECT_EQ(with_action("'M{d},{speed},{d},{speed},{d},{speed}'", "variant: c116, axes: 5"), "");
}

TEST(TechnoModels, SpeedsAndDistancesMustStayInTheControllersRange) {
  const auto unlimited =
      errors_of(model("variant: it116g", "", "  fast: {type: int32, default: 100}\n",
                      "  go: {code: 1, steps: ['a{d},{fast}']}\n"));
  EXPECT_NE(unlimited.find("speed '{fast}' can be -2147483648..2147483647, the controller takes "
                           "30..10000 (give the setpoint or point min/max)"),
            std::string::npos)
      << unlimited;
  const auto literal = with_action("'a100,20'", "variant: it116g");
  EXPECT_NE(literal.find("speed '20' can be 20"), std::string::npos) << literal;
  const auto far = with_action("'a9000000,100'", "variant: it116g");
  EXPECT_NE(far.find("distance '9000000'"), std::string::npos) << far;
}

TEST(TechnoModels, AxisMasksMustNameDefinedAxesOnly) {
  const auto xz = errors_of(model("variant: c116, axes: 5", "",
                                  "  mask: {type: uint16, min: 1, max: 7, default: 1}\n",
                                  "  home: {code: 1, steps: ['R{mask}']}\n"));
  EXPECT_NE(xz.find("axis mask '{mask}' can be 1..7; with axes 5 defined"), std::string::npos)
      << xz;
  EXPECT_EQ(errors_of(model("variant: c116, axes: 5", "",
                            "  mask: {type: uint16, min: 4, max: 5, default: 4}\n",
                            "  home: {code: 1, steps: ['R{mask}']}\n")),
            "");
  EXPECT_NE(with_action("n8").find("axis mask"), std::string::npos);
  EXPECT_EQ(with_action("n7"), "");
}

TEST(TechnoModels, InitialisationIsTheModelsAxesAndOnlyAnAction) {
  EXPECT_EQ(with_action("'7'"), "");
  EXPECT_NE(with_action("'3'").find("must be the model's axes option (7)"), std::string::npos);
  EXPECT_NE(with_action("'6'").find("axes definition"), std::string::npos);
  const auto as_point = with_points("  axes: {type: uint16, write: '7'}\n");
  EXPECT_NE(as_point.find("clears the program memory; put it in an action"), std::string::npos)
      << as_point;
}

TEST(TechnoModels, C142OnlyCommandsNeedTheC142) {
  EXPECT_EQ(with_action("z1"), "");
  const auto e = with_action("z1", "variant: c116");
  EXPECT_NE(e.find("exists only on the C142"), std::string::npos) << e;
  EXPECT_NE(with_action("f-1", "variant: c10, axes: 3").find("only on the C142"),
            std::string::npos);
  const auto quadrant = with_action("'Y100,{speed},0,10,10,{speed},1'");
  EXPECT_NE(quadrant.find("must be exactly -1 or 1"), std::string::npos) << quadrant;
}

TEST(TechnoModels, RawBytesAndUrgency) {
  EXPECT_EQ(with_action("{send: '<stop>', urgent: true}"), "");
  const auto urgent = with_action("{send: k, urgent: true}");
  EXPECT_NE(urgent.find("only <stop> and <reset> may be urgent"), std::string::npos) << urgent;
  const auto wide =
      errors_of(model("variant: c142", "", "", "  go: {code: 1, bus_wide: true, steps: [k]}\n"));
  EXPECT_NE(wide.find("no broadcast address"), std::string::npos) << wide;
}

TEST(TechnoModels, ReadsMustBeQueriesWithTheirFormat) {
  const auto decimal = with_points("  y: {type: int32, read: P, poll: fast}\n");
  EXPECT_NE(decimal.find("give format: hex24"), std::string::npos) << decimal;
  const auto units = with_points(
      "  y: {type: int32, read: {request: P, field: 4, format: hex24}, "
      "poll: fast}\n");
  EXPECT_NE(units.find("needs the steps_per_unit option"), std::string::npos) << units;
  const auto no_query = with_points(
      "  y: {type: int32, read: {request: n7, format: hex}, "
      "poll: fast}\n");
  EXPECT_NE(no_query.find("is no query"), std::string::npos) << no_query;
}

TEST(TechnoModels, PointWritesCannotWaitForMotion) {
  const auto e = with_points("  go: {type: int32, write: 'a{value},100', min: 0, max: 10}\n",
                             "variant: it116g");
  EXPECT_NE(e.find("waits for or starts a motion; put it in an action"), std::string::npos) << e;
  const auto poke = with_points(
      "  o: {type: uint16, write: 'B100,{value}', max: 255}\n"
      "  p: {type: uint16, write: 'B65529,{value}'}\n");
  test::expect_contains(poke, {"lower addresses are EPROM",
                               "data '{value}' can be 0..65535, the controller takes 0..255"});
}

TEST(TechnoModels, TextRules) {
  EXPECT_NE(with_action("'@0k'").find("the family adds '@<device>'"), std::string::npos);
  EXPECT_NE(with_action("'n 7'").find("canonical form without spaces"), std::string::npos);
  EXPECT_NE(with_action("'i'").find("program downloads"), std::string::npos);
  EXPECT_NE(with_action("'t'").find("trace mode"), std::string::npos);
  EXPECT_NE(with_action("'q'").find("is no C-series command"), std::string::npos);
  EXPECT_NE(with_action("'n{speed:x}'").find("values are decimal"), std::string::npos);
}

TEST(TechnoModels, OptionsAreChecked) {
  const auto e = with_options(
      "variant: c999, axes: 6, acceleration: 60, speed_up: 1, "
      "position_reply: maybe, stop_bytes: 3, travel: -5, "
      "init_on_connect: perhaps, timeout_margin: soon");
  test::expect_contains(
      e, {"option variant: expected it116g, c10, c116 or c142, found 'c999'",
          "option axes: expected 1, 3, 5 or 7, found '6'",
          "option acceleration: expected 25, 50, 75 or 100, found '60'",
          "unknown techno-c option 'speed_up'", "option position_reply: expected auto, bare or ack",
          "option stop_bytes: expected 1 or 2, found '3'", "option travel: '-5'",
          "option init_on_connect: expected true or false, found 'perhaps'",
          "option timeout_margin: expected a duration"});
  EXPECT_NE(with_options("variant: it116g, axes: 7").find("single-axis"), std::string::npos);
  EXPECT_NE(with_options("axes: 7").find("option variant is required"), std::string::npos);
}

TEST(TechnoModels, MergedProfilesAreConservative) {
  techno::Profile fast, slow;
  fast.model = "fast";
  slow.model = "slow";
  slow.acceleration = 25000;
  slow.travel = {100000, 1, 1};
  fast.steps_per_unit = std::array<double, 3>{100, 100, 100};
  slow.steps_per_unit = std::array<double, 3>{2540, 2540, 2540};
  const auto m = techno::merge_profiles({fast, slow});
  EXPECT_EQ(m.acceleration, 25000);
  EXPECT_EQ(m.travel[0], 100000);
  EXPECT_EQ(m.travel[1], 50000);
  EXPECT_FALSE(m.steps_per_unit);  // units disagree: no unit fields
  const auto same = techno::merge_profiles({fast, fast});
  EXPECT_TRUE(same.steps_per_unit);
}

}  // namespace
}  // namespace fieldgate
