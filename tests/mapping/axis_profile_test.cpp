// The axis profile's state diagram, refusals and the models' axis_profile: sections.
#include <gtest/gtest.h>

#include "mapping/axis_profile.hpp"
#include "mapping/model_loader.hpp"

namespace fieldgate {
namespace {

AxisObservation enabled_axis() {
  AxisObservation o;
  o.enabled = true;
  return o;
}

TEST(AxisProfileState, ErrorStopWinsUntilResetAndErrorClear) {
  auto o = enabled_axis();
  o.error = true;
  EXPECT_EQ(derive_state(o), PlcopenState::error_stop);
  o.error = false;
  o.error_latched = true;
  o.command = ProfileCommand::move_absolute;
  o.status = CommandStatus::busy;
  EXPECT_EQ(derive_state(o), PlcopenState::error_stop);
  o.enabled = false;
  EXPECT_EQ(derive_state(o), PlcopenState::error_stop);
}

TEST(AxisProfileState, FollowsTheCommandInProgress) {
  auto o = enabled_axis();
  EXPECT_EQ(derive_state(o), PlcopenState::standstill);
  o.status = CommandStatus::busy;
  o.command = ProfileCommand::home;
  EXPECT_EQ(derive_state(o), PlcopenState::homing);
  o.command = ProfileCommand::move_relative;
  EXPECT_EQ(derive_state(o), PlcopenState::discrete_motion);
  o.command = ProfileCommand::halt;
  EXPECT_EQ(derive_state(o), PlcopenState::discrete_motion);
  o.command = ProfileCommand::stop;
  o.moving = true;
  EXPECT_EQ(derive_state(o), PlcopenState::stopping);
  o.command = ProfileCommand::jog_negative;
  o.status = CommandStatus::done;
  EXPECT_EQ(derive_state(o), PlcopenState::continuous_motion);
  o.moving = false;
  EXPECT_EQ(derive_state(o), PlcopenState::standstill);
  o.enabled = false;
  EXPECT_EQ(derive_state(o), PlcopenState::disabled);
}

TEST(AxisProfileState, RefusalsFollowThePlcopenDiagram) {
  EXPECT_EQ(refusal(PlcopenState::disabled, ProfileCommand::move_absolute), kProfileErrorDisabled);
  EXPECT_FALSE(refusal(PlcopenState::disabled, ProfileCommand::power_on));
  EXPECT_FALSE(refusal(PlcopenState::disabled, ProfileCommand::reset));
  EXPECT_EQ(refusal(PlcopenState::error_stop, ProfileCommand::home), kProfileErrorErrorStop);
  EXPECT_FALSE(refusal(PlcopenState::error_stop, ProfileCommand::reset));
  EXPECT_FALSE(refusal(PlcopenState::error_stop, ProfileCommand::power_off));
  EXPECT_EQ(refusal(PlcopenState::stopping, ProfileCommand::jog_positive), kProfileErrorStopping);
  EXPECT_FALSE(refusal(PlcopenState::stopping, ProfileCommand::stop));
  EXPECT_FALSE(refusal(PlcopenState::discrete_motion, ProfileCommand::move_absolute));
}

TEST(AxisProfileNames, EveryValueHasItsOwnNameAndIsFoundByIt) {
  for (int i = 0; i < kStatusBitCount; ++i)
    EXPECT_EQ(status_bit_named(to_string(static_cast<StatusBit>(i))), static_cast<StatusBit>(i));
  for (uint16_t i = 1; i < kProfileCommandCount; ++i)
    EXPECT_EQ(profile_command_named(to_string(static_cast<ProfileCommand>(i))),
              static_cast<ProfileCommand>(i));
  for (int i = 0; i < kProfileSetpointCount; ++i)
    EXPECT_EQ(profile_setpoint_named(to_string(static_cast<ProfileSetpoint>(i))),
              static_cast<ProfileSetpoint>(i));
  EXPECT_FALSE(profile_command_named("none"));
  EXPECT_FALSE(status_bit_named("Enabled"));
  EXPECT_EQ(to_string(PlcopenState::error_stop), "ErrorStop");
  EXPECT_EQ(to_string(CommandStatus::aborted), "aborted");
  EXPECT_EQ(to_string(static_cast<PlcopenState>(7)), "?");
}

TEST(AxisProfileModels, EveryShippedMotionModelMapsEveryCommandOrListsIt) {
  Diagnostics d;
  ModelLibrary library;
  library.load_directory(std::string(FIELDGATE_SOURCE_DIR) + "/config/models", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  for (const char* name :
       {"copley-amplifier", "ims-indexer", "centent-cn0170", "whedco-cmc-xy", "whedco-cmc",
        "techno-c10", "techno-c116", "techno-c142", "techno-it116g", "canopen-cia402"}) {
    const auto model = library.find(name);
    ASSERT_TRUE(model) << name;
    ASSERT_FALSE(model->profile_axes.empty()) << name;
    for (const auto& axis : model->profile_axes) {
      EXPECT_TRUE(axis.supports(ProfileCommand::move_absolute)) << name;
      EXPECT_TRUE(axis.supports(ProfileCommand::stop)) << name;
      EXPECT_TRUE(axis.supports(ProfileCommand::reset)) << name;
    }
  }
  EXPECT_EQ(library.find("centent-cn0170")->profile_axes.size(), 2u);
  EXPECT_EQ(library.find("whedco-cmc")->profile_axes.size(), 4u);
  EXPECT_FALSE(library.find("ims-indexer")->profile_axes[0].supports(ProfileCommand::power_on));
}

TEST(AxisProfileModels, ACommandNeitherMappedNorUnsupportedIsAnError) {
  Diagnostics d;
  load_model_text(R"(model: m
family: copley-ascii
points:
  pos: {type: int32, read: g r0x32, poll: fast}
actions:
  go: {code: 1, steps: [t 1]}
axis_profile:
  axis:
    position: pos
    status: {enabled: true, moving: {point: pos, bit: 0}}
    commands: {move_absolute: go}
    unsupported: [power_on]
)",
                  "m.yaml", d);
  EXPECT_FALSE(d.ok());
  EXPECT_NE(d.to_text().find("command home is neither mapped"), std::string::npos) << d.to_text();
}

constexpr const char* kResetModel = R"(model: m
family: copley-ascii
poll_classes: {fast: 100ms}
points:
  pos: {type: int32, read: g r0x32, poll: fast}
actions:
  go: {code: 1, steps: [t 1]}
  clear: {code: 2, steps: [t 2]}
axis_profile:
  axis:
    position: pos
    status: {enabled: true, moving: {point: pos, bit: 0}}
    commands: {move_absolute: go, reset: RESET}
    reset_only_in_error_stop: ONLY
    unsupported: [power_on, power_off, home, move_relative, jog_positive, jog_negative, stop, halt]
)";

std::string reset_model(const std::string& reset, const std::string& only) {
  std::string text = kResetModel;
  text.replace(text.find("RESET"), 5, reset);
  text.replace(text.find("ONLY"), 4, only);
  return text;
}

TEST(AxisProfileModels, ResetOnlyInErrorStopIsReadAndNeedsAReset) {
  {
    Diagnostics d;
    const auto model = load_model_text(reset_model("clear", "true"), "m.yaml", d);
    ASSERT_TRUE(d.ok()) << d.to_text();
    EXPECT_TRUE(model->profile_axes.at(0).reset_only_in_error_stop);
  }
  {
    Diagnostics d;
    const auto model = load_model_text(reset_model("clear", "off"), "m.yaml", d);
    ASSERT_TRUE(d.ok()) << d.to_text();
    EXPECT_FALSE(model->profile_axes.at(0).reset_only_in_error_stop);
  }
  {
    Diagnostics d;
    load_model_text(reset_model("[]", "true"), "m.yaml", d);
    EXPECT_FALSE(d.ok());
    EXPECT_NE(d.to_text().find("reset_only_in_error_stop needs a reset action"), std::string::npos)
        << d.to_text();
  }
  {
    Diagnostics d;
    load_model_text(reset_model("clear", "sometimes"), "m.yaml", d);
    EXPECT_FALSE(d.ok());
    EXPECT_NE(d.to_text().find("m.yaml:"), std::string::npos) << d.to_text();
  }
}

// A CiA 402 fault reset rewrites the controlword, which would switch an enabled drive off.
TEST(AxisProfileModels, Cia402ResetsOnlyInErrorStop) {
  Diagnostics d;
  ModelLibrary library;
  library.load_directory(std::string(FIELDGATE_SOURCE_DIR) + "/config/models", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  EXPECT_TRUE(library.find("canopen-cia402")->profile_axes.at(0).reset_only_in_error_stop);
  EXPECT_FALSE(library.find("copley-amplifier")->profile_axes.at(0).reset_only_in_error_stop);
}

// Two axes of one node commanded in the same scan: a setpoint that axis y's command sets and
// axis x's action sends, without x setting it, would go out with y's value.
constexpr const char* kTwoAxisModel = R"(model: m
family: techno-c
poll_classes: {fast: 100ms}
points:
  px: {type: int32, read: "@0P", poll: fast}
  py: {type: int32, read: {request: "@0P", field: 1}, poll: fast}
  fsx: {type: int32, read: "FSX?", write: "FSX{value}", poll: fast, min: 0, none: 0}
setpoints:
  tx: {type: int32}
  ty: {type: int32}
  speed: {type: int32, default: 100, none: 0}
actions:
  move: {code: 1, steps: ["M{tx},{speed},{ty},{speed}"]}
axis_profile:
  x:
    position: px
    reset_count: py
    position_tolerance: 3
    status: {enabled: true, moving: {point: px, bit: 0}}
    setpoints: {target: tx}
    hold: {ty: py}
    commands: {move_absolute: move}
    unsupported: [power_on, power_off, home, move_relative, jog_positive, jog_negative, stop, halt, reset]
  y:
    position: py
    status: {enabled: true, moving: {point: py, bit: 0}}
    setpoints: {target: ty, velocity: speed}
    hold: {tx: px}
    commands: {move_absolute: move}
    unsupported: [power_on, power_off, home, move_relative, jog_positive, jog_negative, stop, halt, reset]
)";

TEST(AxisProfileModels, ASetpointOneAxisSendsAndOnlyAnotherSetsIsRefusedWhereItIsUsed) {
  Diagnostics d;
  load_model_text(kTwoAxisModel, "m.yaml", d);
  EXPECT_FALSE(d.ok());
  const std::string text = d.to_text();
  EXPECT_NE(text.find("axis_profile x commands move_absolute: action move sends setpoint "
                      "'speed', which axis y's commands set and axis x's do not"),
            std::string::npos)
      << text;
  // At the line of x's commands (line 22 of the text above), with its column.
  EXPECT_NE(text.find("m.yaml:22:"), std::string::npos) << text;
  EXPECT_EQ(text.find("axis_profile y commands"), std::string::npos) << text;
}

TEST(AxisProfileModels, ASetpointEveryAxisSetsItselfIsAccepted) {
  std::string text = kTwoAxisModel;
  text.replace(text.find("    hold: {ty: py}"), 18, "    hold: {ty: py}\n    fixed: {speed: 50}");
  Diagnostics d;
  const auto model = load_model_text(text, "m.yaml", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  const auto& x = model->profile_axes.at(0);
  EXPECT_EQ(x.position_tolerance, 3);
  EXPECT_EQ(x.reset_count, "py");
  EXPECT_EQ(model->find_setpoint("speed")->none, 0);
  EXPECT_EQ(model->find_point("fsx")->none, 0);
  EXPECT_FALSE(model->find_setpoint("tx")->none);
}

TEST(AxisProfileModels, ANegativeToleranceOrAnUnpolledResetCountIsAnError) {
  std::string text = kTwoAxisModel;
  text.replace(text.find("position_tolerance: 3"), 21, "position_tolerance: -1");
  text.replace(text.find("reset_count: py"), 15, "reset_count: nothing");
  Diagnostics d;
  load_model_text(text, "m.yaml", d);
  EXPECT_NE(d.to_text().find("position_tolerance"), std::string::npos) << d.to_text();
  EXPECT_NE(d.to_text().find("reset_count: unknown point 'nothing'"), std::string::npos)
      << d.to_text();
}

// Every shipped model passes the check: the axes of the Techno and Whedco models fill every
// setpoint their commands send (the others' speeds are fixed: an axis that stays put ignores
// its speed).
TEST(AxisProfileModels, ShippedMultiAxisModelsFillWhatTheirCommandsSend) {
  Diagnostics d;
  ModelLibrary library;
  library.load_directory(std::string(FIELDGATE_SOURCE_DIR) + "/config/models", d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  EXPECT_EQ(library.find("whedco-cmc-xy")->find_point("x_jog_speed")->none, 0);
  EXPECT_EQ(library.find("centent-cn0170")->profile_axes.at(0).reset_count, "resets");
}

}  // namespace
}  // namespace fieldgate
