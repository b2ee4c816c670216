#include <gtest/gtest.h>

#include <ostream>
#include <string>
#include <vector>

#include "mapping/model_loader.hpp"

namespace fieldgate {
namespace {

std::string first_error(const std::string& yaml) {
  Diagnostics d;
  load_model_text(yaml, "m.yaml", d);
  return d.ok() ? std::string("no error")
                : d.errors().front().message + " @" + std::to_string(d.errors().front().mark.line) +
                      ":" + std::to_string(d.errors().front().mark.column);
}

constexpr const char* kHeader = "model: m\nfamily: copley-ascii\npoll_classes: {fast: 100ms}\n";

TEST(ModelLoader, ShippedCopleyModelLoadsClean) {
  Diagnostics d;
  auto m = load_model_file(FIELDGATE_SOURCE_DIR "/config/models/copley-amplifier.yaml", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  ASSERT_TRUE(m);
  EXPECT_EQ(m->family, "copley-ascii");
  const auto* status = m->find_point("event_status");
  ASSERT_TRUE(status);
  ASSERT_TRUE(status->find_bit("in_motion"));
  EXPECT_EQ(status->find_bit("in_motion")->bit, 27);
  const auto* move = m->find_action("move_absolute");
  ASSERT_TRUE(move);
  ASSERT_TRUE(move->done);
  EXPECT_EQ(move->done->bit, 27);
  // Every action of issue 2 is there.
  for (const char* a :
       {"enable", "disable", "move_absolute", "move_relative", "home", "abort", "clear_faults"})
    EXPECT_TRUE(m->find_action(a)) << a;
}

TEST(ModelLoader, DelayStepsLoad) {
  Diagnostics d;
  auto m = load_model_text(std::string(kHeader) +
                               "actions:\n  reset:\n    code: 1\n    steps:\n      - r\n"
                               "      - {delay: 500ms}\n      - t 0\n",
                           "m.yaml", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  ASSERT_EQ(m->actions[0].steps.size(), 3u);
  EXPECT_EQ(m->actions[0].steps[1].kind, ActionStep::Kind::delay);
  EXPECT_EQ(m->actions[0].steps[1].duration, std::chrono::milliseconds(500));
}

// Issue 50: `failed:` takes one condition or a list; each entry has its own error_from.
TEST(ModelLoader, FailedTakesOneConditionOrAList) {
  const std::string points =
      "points:\n  s: {type: uint32, read: g r0xa0, poll: fast, bits: {limit: 3}}\n"
      "  e: {type: int32, read: g r0xa4, poll: fast}\n"
      "  c: {type: int32, read: g r0xa5, poll: fast}\n";
  Diagnostics d;
  auto one = load_model_text(kHeader + points +
                                 "actions:\n  go:\n    code: 1\n    steps: [t 1]\n"
                                 "    failed: {point: e, equals: 0, error_from: c}\n",
                             "m.yaml", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  ASSERT_EQ(one->actions[0].failed.size(), 1u);
  EXPECT_EQ(one->actions[0].failed[0].point, "e");
  EXPECT_EQ(one->actions[0].failed[0].error_from, "c");

  auto list = load_model_text(kHeader + points +
                                  "actions:\n  go:\n    code: 1\n    steps: [t 1]\n"
                                  "    failed:\n      - {point: e, equals: 0}\n"
                                  "      - {point: s, bit: limit, equals: 1, error_from: c}\n",
                              "m.yaml", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  const auto& failed = list->actions[0].failed;
  ASSERT_EQ(failed.size(), 2u);
  EXPECT_EQ(failed[0].point, "e");
  EXPECT_EQ(failed[0].equals, 0);
  EXPECT_EQ(failed[0].error_from, "");
  EXPECT_EQ(failed[1].point, "s");
  EXPECT_EQ(failed[1].bit, 3);
  EXPECT_EQ(failed[1].equals, 1);
  EXPECT_EQ(failed[1].error_from, "c");

  auto none =
      load_model_text(kHeader + points + "actions:\n  go: {code: 1, steps: [t 1]}\n", "m.yaml", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  EXPECT_TRUE(none->actions[0].failed.empty());
}

// A model with one mistake: the first error names it (all of `expected`, position included).
// A model of the header's family and poll class, then `body`.
std::string with_header(const std::string& body) {
  return kHeader + body;
}

struct BadModel {
  const char* name;
  std::string yaml;
  std::vector<std::string> expected;
};

void PrintTo(const BadModel& model, std::ostream* out) {
  *out << model.name;
}

class ModelLoaderError : public ::testing::TestWithParam<BadModel> {};

TEST_P(ModelLoaderError, IsNamedPrecisely) {
  const std::string e = first_error(GetParam().yaml);
  for (const std::string& expected : GetParam().expected)
    EXPECT_NE(e.find(expected), std::string::npos) << "expected " << expected << " in " << e;
}

INSTANTIATE_TEST_SUITE_P(
    ModelLoader, ModelLoaderError,
    ::testing::Values(
        BadModel{"UnknownKeyNamesLineColumnAndAlternatives",
                 with_header("points:\n  p:\n    type: int32\n    red: g r0x32\n    poll: fast\n"),
                 {"unknown key 'red'", "read", "@7:5"}},
        BadModel{
            "WrongTypeIsReported",
            with_header("points:\n  p:\n    type: float64\n    read: g r0x32\n    poll: fast\n"),
            {"unknown type 'float64'", "@6:11"}},
        BadModel{"UnknownPollClass",
                 with_header("points:\n  p:\n    type: int32\n    read: g r0x32\n    poll: slow\n"),
                 {"unknown poll class 'slow' (defined: fast)"}},
        BadModel{
            "ActionPlaceholderMustBeASetpoint",
            with_header("actions:\n  go:\n    code: 1\n    steps:\n      - s r0xca {target}\n"),
            {"{target}", "not a setpoint"}},
        BadModel{
            "DuplicateActionCodes",
            with_header("actions:\n  a: {code: 1, steps: [t 1]}\n  b: {code: 1, steps: [t 0]}\n"),
            {"code 1 is already used by action a"}},
        BadModel{"DuplicatePointNames",
                 with_header("points:\n  p: {type: int16, read: g r0x1, poll: fast}\n"
                             "  p: {type: int16, read: g r0x2, poll: fast}\n"),
                 {"'p' is defined twice"}},
        BadModel{
            "ConditionBitMustExist",
            with_header("points:\n  s: {type: uint32, read: g r0xa0, poll: fast, bits: {m: 27}}\n"
                        "actions:\n  go: {code: 1, steps: [t 1], done: {point: s, bit: moving, "
                        "equals: 0}}\n"),
            {"no bit named 'moving'"}},
        BadModel{"LimitsMustFitTheType",
                 with_header(
                     "points:\n  p:\n    type: int16\n    write: s r0x1 {value}\n    max: 70000\n"),
                 {"max 70000 does not fit int16"}},
        BadModel{"WriteTakesOnlyValue",
                 with_header("points:\n  p:\n    type: int16\n    write: s r0x1 {v}\n"),
                 {"only {value}"}},
        BadModel{"FailedListMustNotBeEmpty",
                 with_header("points:\n  s: {type: int32, read: g r0xa0, poll: fast}\n"
                             "actions:\n  go:\n    code: 1\n    steps: [t 1]\n    failed: []\n"),
                 {"action go failed: an empty list", "@10:13"}},
        BadModel{"FailedListEntryMustBeACondition",
                 with_header("points:\n  s: {type: int32, read: g r0xa0, poll: fast}\n"
                             "actions:\n  go:\n    code: 1\n    steps: [t 1]\n    failed:\n"
                             "      - {point: s, equals: 1}\n      - s\n"),
                 {"action go failed condition 2: expected a condition", "found 's'", "@12:9"}},
        BadModel{"FailedListEntryIsCheckedAsACondition",
                 with_header("points:\n  s: {type: int32, read: g r0xa0, poll: fast}\n"
                             "actions:\n  go:\n    code: 1\n    steps: [t 1]\n    failed:\n"
                             "      - {point: s, equals: 1}\n      - {point: t, equals: 1}\n"),
                 {"action go failed condition 2: unknown point 't'", "@12:17"}},
        BadModel{"FailedListEntryErrorFromMustBePolled",
                 with_header("points:\n  s: {type: int32, read: g r0xa0, poll: fast}\n"
                             "actions:\n  go:\n    code: 1\n    steps: [t 1]\n    failed:\n"
                             "      - {point: s, equals: 1, error_from: e}\n"),
                 {"action go failed condition 1: error_from names 'e', which is no polled point",
                  "@11:43"}},
        BadModel{"SyntaxErrorHasPosition", "model: m\nfamily: [unclosed\n", {"YAML syntax"}}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(ModelLoader, CanopenObjectsParse) {
  Diagnostics d;
  auto m = load_model_text(
      "model: c\nfamily: canopen\npoll_classes: {fast: 50ms}\npoints:\n"
      "  pos: {type: int32, read: {object: '0x6064:0', data_type: INTEGER32}, poll: fast}\n",
      "c.yaml", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  ASSERT_TRUE(m->points[0].read->object);
  EXPECT_EQ(m->points[0].read->object->index, 0x6064);
  EXPECT_EQ(m->points[0].read->object->data_type, "INTEGER32");
}

}  // namespace
}  // namespace fieldgate
