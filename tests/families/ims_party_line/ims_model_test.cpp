// The shipped model and the family's checks of models (validate_model).
#include <gtest/gtest.h>

#include "drivers/ims_party_line/ims_family.hpp"
#include "mapping/model_loader.hpp"
#include "mapping/register_map.hpp"

namespace fieldgate {
namespace {

constexpr const char* kHeader = "model: m\nfamily: ims-party-line\npoll_classes: {fast: 100ms}\n";

// Every error of loading and validating `yaml`, one per line; "" when it is clean.
std::string errors_of(const std::string& yaml) {
  Diagnostics d;
  auto model = load_model_text(yaml, "m.yaml", d);
  if (!d.ok()) return "load: " + d.to_text();
  ImsPartyLineFamily family;
  family.validate_model(*model, d);
  return d.ok() ? std::string() : d.to_text();
}

TEST(ImsModel, ShippedModelLoadsAndValidatesClean) {
  Diagnostics d;
  auto m = load_model_file(FIELDGATE_SOURCE_DIR "/config/models/ims-indexer.yaml", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  ASSERT_TRUE(m);
  ImsPartyLineFamily family;
  family.validate_model(*m, d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  EXPECT_EQ(m->family, "ims-party-line");
  for (const char* a : {"move_absolute", "move_relative", "jog", "stop_jog", "home", "set_origin",
                        "save_parameters", "soft_stop", "hard_stop", "reset_all", "stop_jog_all"})
    EXPECT_TRUE(m->find_action(a)) << a;
  for (const char* a : {"soft_stop", "hard_stop", "reset_all", "stop_jog_all"})
    EXPECT_TRUE(m->find_action(a)->bus_wide) << a;
  for (const char* a : {"move_absolute", "save_parameters", "home", "set_origin"})
    EXPECT_FALSE(m->find_action(a)->bus_wide) << a;
  EXPECT_TRUE(m->find_action("hard_stop")->steps.front().urgent);
  EXPECT_EQ(m->find_action("hard_stop")->steps.front().command.source(), "\x1b");
  EXPECT_EQ(m->find_action("reset_all")->steps.front().command.source(), "\x03");
  // The S command appears only in the save action.
  for (const auto& a : m->actions)
    for (const auto& s : a.steps)
      if (s.command.source() == "S") {
        EXPECT_EQ(a.name, "save_parameters");
      }
  for (const auto& p : m->points) {
    if (p.read) {
      EXPECT_NE(p.read->request.source(), "S");
    }
    if (p.write) {
      EXPECT_NE(p.write->request.source(), "S");
    }
  }
}

TEST(ImsModel, ShippedModelRegisterLayout) {
  Diagnostics d;
  auto m = load_model_file(FIELDGATE_SOURCE_DIR "/config/models/ims-indexer.yaml", d);
  ASSERT_TRUE(m);
  auto map = RegisterMap::build({{1, 0, "a", "ims", m}}, WordOrder::high_first, d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  const UnitMap* u = map.unit(1);
  ASSERT_TRUE(u);
  const auto name_at = [&](Table t, uint16_t a) {
    const RegisterEntry* e = u->find(t, a);
    return e ? e->name : std::string("-");
  };
  EXPECT_EQ(name_at(Table::input_registers, 0), "position");
  EXPECT_EQ(name_at(Table::input_registers, 2), "status");
  EXPECT_EQ(name_at(Table::input_registers, 5), "io");
  EXPECT_EQ(name_at(Table::holding_registers, 0), "outputs");
  EXPECT_EQ(name_at(Table::holding_registers, 5), "settling_delay");
  EXPECT_EQ(name_at(Table::holding_registers, 110), "target");
  EXPECT_EQ(name_at(Table::holding_registers, 114), "velocity");
  EXPECT_EQ(name_at(Table::holding_registers, 117), "jog_velocity");
  EXPECT_EQ(name_at(Table::holding_registers, 121), "run_current");
  EXPECT_NE(name_at(Table::discrete_inputs, 0).find("moving"), std::string::npos);
  EXPECT_NE(name_at(Table::discrete_inputs, 2).find("homing"), std::string::npos);
  EXPECT_NE(name_at(Table::discrete_inputs, 18).find("out1"), std::string::npos);
  EXPECT_NE(name_at(Table::discrete_inputs, 20).find("out3"), std::string::npos);
}

struct BadModel {
  const char* name;
  std::string yaml;
  const char* expected;
};

void PrintTo(const BadModel& m, std::ostream* os) {
  *os << m.name;
}

std::string point(const char* spec) {
  return std::string(kHeader) + "points:\n  p: " + spec + "\n";
}
std::string action(const char* spec) {
  return std::string(kHeader) +
         "points:\n  s: {type: uint16, read: \"^\", poll: fast}\n"
         "setpoints:\n  target: {type: int32, min: -8388607, max: 8388607}\n"
         "  wide: {type: int32}\n  small: {type: uint16, max: 255}\n"
         "actions:\n  a: " +
         spec + "\n";
}

class ImsModelErrors : public ::testing::TestWithParam<BadModel> {};

TEST_P(ImsModelErrors, NamePreciseReason) {
  const auto& c = GetParam();
  const std::string e = errors_of(c.yaml);
  EXPECT_NE(e.find(c.expected), std::string::npos) << "got: " << (e.empty() ? "(clean)" : e);
  EXPECT_NE(e.find("m.yaml:"), std::string::npos) << e;
}

INSTANTIATE_TEST_SUITE_P(
    Checks, ImsModelErrors,
    ::testing::Values(
        BadModel{"Cr", point("{type: int32, read: \"Z\\r\", poll: fast}"), "CR on a party line"},
        BadModel{"Lf", point("{type: int32, read: \"Z\\n\", poll: fast}"), "ends every line"},
        BadModel{"Hex", point("{type: uint16, write: \"A{value:x}\"}"), "decimal"},
        BadModel{"HexRead", point("{type: int32, read: {request: Z, format: hex}, poll: fast}"),
                 "answer in decimal"},
        BadModel{"Unknown", point("{type: int32, read: x, poll: fast}"),
                 "does not start with an IMS command character"},
        BadModel{"NoReadback", point("{type: uint16, read: V, poll: fast}"), "no readback"},
        BadModel{"ContinuousZ", point("{type: int32, read: Z1, poll: fast}"),
                 "continuous position output"},
        BadModel{"ExamineRead", point("{type: int32, read: X, poll: fast}"), "\"32."},
        BadModel{"ManyNvmBytes", point("{type: int32, read: \"[1984 36\", poll: fast}"),
                 "more than 10 bytes"},
        BadModel{"FieldOfZ", point("{type: int32, read: {request: Z, field: 1}, poll: fast}"),
                 "only '[' returns more than one value"},
        BadModel{"SaveAsWrite", point("{type: uint16, write: S}"), "never a point write"},
        BadModel{"MoveAsWrite", point("{type: int32, write: \"R{value}\"}"), "starts motion"},
        BadModel{"QueryAsWrite", point("{type: int32, write: Z}"), "is a query"},
        BadModel{"SoftStopWrite", point("{type: uint16, write: \"@\"}"), "typed Global"},
        BadModel{"WaitInAction", action("{code: 1, steps: [W0]}"), "stalls the chain"},
        BadModel{"Program", action("{code: 1, steps: [P0]}"), "program mode"},
        BadModel{"ListQ", action("{code: 1, steps: [Q]}"), "does not function"},
        BadModel{"Jump", action("{code: 1, steps: [\"J 0 5\"]}"), "program instruction"},
        BadModel{"RawNvm", action("{code: 1, steps: [\"\\\\ 100 20\"]}"), "raw EEPROM"},
        BadModel{"Erase", action("{code: 1, steps: [C8]}"), "commissioning"},
        BadModel{"Trace", action("{code: 1, steps: [\"G 0 1\"]}"), "trace output"},
        BadModel{"EscapeNotBusWide", action("{code: 1, steps: [\"\\e\"]}"),
                 "ESC hard-stops every axis"},
        BadModel{"ResetNotBusWide", action("{code: 1, steps: [\"\\x03\"]}"),
                 "^C resets every axis"},
        BadModel{"EscapeInLine", action("{code: 1, bus_wide: true, steps: [\"Z\\e\"]}"),
                 "sent on its own"},
        BadModel{"SoftStopNotBusWide", action("{code: 1, steps: [\"@\"]}"), "bus_wide: true"},
        BadModel{"BadGlobalSoftStop", action("{code: 1, bus_wide: true, steps: [\"@5\"]}"),
                 "'@', '@0' or '@1'"},
        BadModel{"ExplicitStar", action("{code: 1, bus_wide: true, steps: [\"*M0\"]}"),
                 "adds the global address"},
        BadModel{"StarNeedsFirmware", action("{code: 1, bus_wide: true, steps: [M0]}"),
                 "firmware 1.15 or later"},
        BadModel{"BusWideRead", action("{code: 1, bus_wide: true, steps: [Z]}"), "cannot read"},
        BadModel{"BusWideSave", action("{code: 1, bus_wide: true, steps: [S]}"), "save each axis"},
        BadModel{"UrgentNotGlobal", action("{code: 1, steps: [{send: M0, urgent: true}]}"),
                 "sent urgently"},
        BadModel{"TooLong", action("{code: 1, steps: [\"T{wide} {small}\"]}"),
                 "can render to 16 characters"},
        BadModel{"BadRender", action("{code: 1, steps: [\"K{small},{small}\"]}"),
                 "which is not a command character with up to two numbers"},
        BadModel{"UnknownOption", std::string(kHeader) + "options: {echo: always}\n",
                 "unknown ims-party-line option 'echo'"},
        BadModel{"BadFirmware", std::string(kHeader) + "options: {firmware: new}\n",
                 "option firmware"},
        BadModel{"BadLimit", std::string(kHeader) + "options: {line_limit: 1}\n",
                 "option line_limit"},
        BadModel{"BadBool", std::string(kHeader) + "options: {addressed_soft_stop: maybe}\n",
                 "true or false"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(ImsModel, OptionsWidenWhatIsAllowed) {
  EXPECT_EQ(
      errors_of(action("{code: 1, steps: [\"@\"]}") + "options: {addressed_soft_stop: true}\n"),
      "");
  EXPECT_EQ(errors_of(action("{code: 1, bus_wide: true, steps: [M0]}") +
                      "options: {firmware: \"1.15\"}\n"),
            "");
  // "R-8388607" is 9 characters: fine with or without the name counted.
  EXPECT_EQ(errors_of(action("{code: 1, steps: [\"R{target}\"]}") +
                      "options: {line_limit_counts_name: true}\n"),
            "");
  // "+-8388607" goes out as "-8388607".
  EXPECT_EQ(errors_of(action("{code: 1, steps: [\"+{target}\"]}")), "");
  // 12 characters fit; with the name counted they do not.
  const std::string twelve = action("{code: 1, steps: [\"k{target} 56\"]}");
  EXPECT_EQ(errors_of(twelve), "");
  EXPECT_NE(errors_of(twelve + "options: {line_limit_counts_name: true}\n").find("the name counts"),
            std::string::npos);
  EXPECT_NE(errors_of(twelve + "options: {line_limit: 10}\n").find("at most 10"),
            std::string::npos);
}

}  // namespace
}  // namespace fieldgate
