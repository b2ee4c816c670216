// The canopen family's load-time checks: addresses and models, with file:line:column.
#include <gtest/gtest.h>

#include "drivers/canopen/canopen_family.hpp"
#include "mapping/model_loader.hpp"
#include "tests/harness/address_checks.hpp"
#include "tests/harness/text_checks.hpp"

namespace fieldgate {
namespace {

std::string validate_file(const std::string& file) {
  Diagnostics d;
  auto model = load_model_file(FIELDGATE_SOURCE_DIR "/config/models/" + file, d);
  EXPECT_TRUE(model) << d.to_text();
  if (model) CanopenFamily().validate_model(*model, d);
  return d.to_text();
}

std::string validate_text(const std::string& yaml) {
  Diagnostics d;
  auto model = load_model_text(yaml, "m.yaml", d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  if (model) CanopenFamily().validate_model(*model, d);
  return d.to_text();
}

TEST(CanopenFamily, ShippedModelsAreValid) {
  EXPECT_EQ(validate_file("canopen-cia301.yaml"), "");
  EXPECT_EQ(validate_file("canopen-cia402.yaml"), "");
}

TEST(CanopenFamily, Address) {
  CanopenFamily f;
  ASSERT_TRUE(test::expect_address(f, "0x7F", "127", 127));
  std::string error;
  EXPECT_FALSE(f.parse_address("0", error));
  EXPECT_EQ(error, "expected a CANopen node ID 1..127, found '0'");
  EXPECT_EQ(f.name(), "canopen");
  EXPECT_TRUE(make_family("canopen"));
}

// The registry hands out the family base; canopen has the frame shape, not the stream one.
TEST(CanopenFamily, IsAFrameFamilyNotAStreamFamily) {
  const FamilyPtr family = make_family("canopen");
  ASSERT_TRUE(family);
  EXPECT_NE(dynamic_cast<FrameFamily*>(family.get()), nullptr);
  EXPECT_EQ(dynamic_cast<ProtocolFamily*>(family.get()), nullptr);
  const FamilyPtr stream = make_family("copley-ascii");
  ASSERT_TRUE(stream);
  EXPECT_EQ(dynamic_cast<FrameFamily*>(stream.get()), nullptr);
  EXPECT_NE(dynamic_cast<ProtocolFamily*>(stream.get()), nullptr);
}

constexpr const char* kHeader = "model: m\nfamily: canopen\npoll_classes: {slow: 1s}\n";

TEST(CanopenFamily, ManufacturerObjectIsYamlOnly) {
  EXPECT_EQ(validate_text(std::string(kHeader) +
                          "points:\n"
                          "  user_label_0:\n"
                          "    type: uint32\n"
                          "    read: {object: \"0x2000:0\", data_type: VISIBLE_STRING}\n"
                          "    poll: slow\n"
                          "  inject:\n"
                          "    type: uint16\n"
                          "    write: \"write 0x2001:0 UNSIGNED16 {value}\"\n"
                          "actions:\n"
                          "  label:\n"
                          "    code: 1\n"
                          "    steps:\n"
                          "      - write 0x2000:0 \"conveyor left\"\n"
                          "      - read 0x2000:0\n"),
            "");
}

TEST(CanopenFamily, PointErrorsCarryTheirPosition) {
  const auto e = validate_text(std::string(kHeader) +
                               "points:\n"
                               "  position:\n"
                               "    type: int16\n"
                               "    read: {object: \"0x6064:0\", data_type: INTEGER32}\n"
                               "    poll: slow\n"
                               "  target:\n"
                               "    type: int32\n"
                               "    write: {object: \"0x607A:0\", data_type: INTEGER32}\n"
                               "  mode:\n"
                               "    type: int16\n"
                               "    write: \"write 0x6060:0 INTEGER8 {value}\"\n"
                               "  speed:\n"
                               "    type: int32\n"
                               "    read: {object: \"0x6081:0\", data_type: UNSIGNED32}\n"
                               "    write: \"write 0x6083:0 UNSIGNED32 {value}\"\n"
                               "    poll: slow\n"
                               "    min: 0\n");
  test::expect_contains(
      e, {"m.yaml:6:5: error: model m: point position read: INTEGER32 does not fit a "
          "int16 point (use a wider type)",
          "m.yaml:10:5: error: model m: point target write: a canopen point write is "
          "request text the bus runs, e.g. write: \"write 0x607A:0 {value}\"",
          "m.yaml:13:5: error: model m: point mode: values -32768..32767 reach outside "
          "INTEGER8 (-128..127); set min and max"});
  // A speed point reading one object and writing another is allowed (e.g. a setpoint and its
  // actual value); only the request's own checks apply.
  EXPECT_EQ(e.find("point speed"), std::string::npos) << e;
}

TEST(CanopenFamily, StepErrorsCarryTheirPosition) {
  const auto e = validate_text(std::string(kHeader) +
                               "points:\n"
                               "  controlword:\n"
                               "    type: uint16\n"
                               "    write: \"write 0x6040:0 UNSIGNED16 {value}\"\n"
                               "setpoints:\n"
                               "  target: {type: int32}\n"
                               "actions:\n"
                               "  go:\n"
                               "    code: 1\n"
                               "    steps:\n"
                               "      - write controlword 0x0F\n"
                               "      - write 0x607A:0 {target}\n"
                               "      - wait statusword & 0x6F == 0x27\n"
                               "      - nmt reboot\n"
                               "  stop_all:\n"
                               "    code: 2\n"
                               "    bus_wide: true\n"
                               "    steps:\n"
                               "      - nmt stop\n"
                               "      - write controlword 0x02\n");
  test::expect_contains(
      e, {"m.yaml:15:9: error: model m: action go: step 'write 0x607A:0 {target}': no "
          "data type for 0x607A:0",
          "m.yaml:16:9: error: model m: action go: step 'wait statusword & 0x6F == "
          "0x27': 'statusword' is neither INDEX:SUB",
          "m.yaml:17:9: error: model m: action go: step 'nmt reboot': nmt: unknown "
          "command 'reboot'",
          "m.yaml:23:9: error: model m: action stop_all: step 'write controlword "
          "0x02': a bus-wide action may only send NMT commands (SDO has no broadcast)"});
  EXPECT_EQ(e.find("m.yaml:14:"), std::string::npos) << e;
  EXPECT_EQ(e.find("m.yaml:22:"), std::string::npos) << e;
}

TEST(CanopenFamily, APlaceholderThatIsNotAWholeValueIsALoadErrorAtItsStep) {
  const auto e = validate_text(std::string(kHeader) +
                               "points:\n"
                               "  controlword:\n"
                               "    type: uint16\n"
                               "    write: \"write 0x6040:0 UNSIGNED16 {value}\"\n"
                               "  label:\n"
                               "    type: uint16\n"
                               "    write: \"write 0x2000:0 VISIBLE_STRING \\\"{value}\\\"\"\n"
                               "setpoints:\n"
                               "  index: {type: uint16}\n"
                               "  word: {type: uint16}\n"
                               "actions:\n"
                               "  go:\n"
                               "    code: 1\n"
                               "    steps:\n"
                               "      - write 0x{index:X}:0 UNSIGNED16 7\n"
                               "      - write controlword 1{word}\n"
                               "      - write controlword {word}\n");
  test::expect_contains(
      e, {"m.yaml:18:9: error: model m: action go: step 'write 0x{index:X}:0 UNSIGNED16 7': "
          "{index} must stand for the whole value written or waited for (or a wait's mask)",
          "m.yaml:19:9: error: model m: action go: step 'write controlword 1{word}': {word} "
          "must stand for the whole value written or waited for (or a wait's mask)",
          "m.yaml:9:5: error: model m: point label write: {value} must stand for the whole "
          "value written or waited for (or a wait's mask)"});
  EXPECT_EQ(e.find("m.yaml:20:"), std::string::npos) << e;
  EXPECT_EQ(e.find("m.yaml:7:"), std::string::npos) << e;
}

TEST(CanopenFamily, NoOptions) {
  const auto e = validate_text(std::string(kHeader) + "options: {baud: 500k}\npoints: {}\n");
  EXPECT_NE(
      e.find("m.yaml:4:11: error: model m: option 'baud': the canopen family has no model options"),
      std::string::npos)
      << e;
}

}  // namespace
}  // namespace fieldgate
