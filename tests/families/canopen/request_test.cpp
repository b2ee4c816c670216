// The canopen request grammar, point read sources and value decoding.
#include <gtest/gtest.h>

#include "drivers/canopen/canopen_request.hpp"
#include "mapping/model_loader.hpp"

namespace fieldgate::canopen {
namespace {

using namespace std::chrono_literals;

ModelPtr drive_model() {
  Diagnostics d;
  auto m = load_model_file(FIELDGATE_SOURCE_DIR "/config/models/canopen-cia402.yaml", d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  return m;
}

Operation parse_ok(std::string_view text, const Model* model) {
  std::string error;
  auto op = parse_operation(text, model, error);
  EXPECT_TRUE(op) << text << ": " << error;
  return op.value_or(Operation{});
}

std::string parse_error(std::string_view text, const Model* model) {
  std::string error;
  auto op = parse_operation(text, model, error);
  EXPECT_FALSE(op) << text;
  return error;
}

TEST(Request, WriteByIndexAndByPointName) {
  const auto model = drive_model();
  auto op = parse_ok("write 0x6040:0 0x0F", model.get());
  EXPECT_EQ(op.kind, Operation::Kind::write);
  EXPECT_EQ(op.object, (ObjectAddress{0x6040, 0, DataType::unsigned16}));  // type from model
  EXPECT_EQ(op.value, 15);
  op = parse_ok("write controlword 6", model.get());
  EXPECT_EQ(op.object, (ObjectAddress{0x6040, 0, DataType::unsigned16}));
  op = parse_ok("write target_position -2000", model.get());
  EXPECT_EQ(op.object, (ObjectAddress{0x607A, 0, DataType::integer32}));
  EXPECT_EQ(op.value, -2000);
  op = parse_ok("write 0x2001:0 UNSIGNED16 0x2310", nullptr);
  EXPECT_EQ(op.object, (ObjectAddress{0x2001, 0, DataType::unsigned16}));
  op = parse_ok("write 0x2000:0 VISIBLE_STRING \"axis \\\"two\\\"\"", nullptr);
  ASSERT_TRUE(op.text);
  EXPECT_EQ(*op.text, "axis \"two\"");
}

std::shared_ptr<const CompiledOperation> compile_ok(std::string_view text, const Model* model) {
  std::string error;
  const auto command = CommandTemplate::compile(text, error);
  EXPECT_TRUE(command) << text << ": " << error;
  if (!command) return nullptr;
  auto compiled = compile_operation(*command, model, error);
  EXPECT_TRUE(compiled) << text << ": " << error;
  return compiled;
}

std::string compile_error(std::string_view text, const Model* model) {
  std::string error;
  const auto command = CommandTemplate::compile(text, error);
  EXPECT_TRUE(command) << text << ": " << error;
  if (!command) return error;
  EXPECT_FALSE(compile_operation(*command, model, error)) << text;
  return error;
}

TEST(CompiledOperation, PlaceholdersFillTheValueOrTheMaskWithoutParsing) {
  const auto model = drive_model();
  const auto write = compile_ok("write target_position {target}", model.get());
  ASSERT_TRUE(write);
  std::string error;
  const std::vector<int64_t> target{-250000};
  auto op = write->with(target, error);
  ASSERT_TRUE(op) << error;
  EXPECT_EQ(op->kind, Operation::Kind::write);
  EXPECT_EQ(op->object, (ObjectAddress{0x607A, 0, DataType::integer32}));
  EXPECT_EQ(op->value, -250000);

  const auto wait = compile_ok("wait statusword & {mask} == {state} within 2s", model.get());
  ASSERT_TRUE(wait);
  const std::vector<int64_t> mask_and_state{0x6F, 0x27};
  op = wait->with(mask_and_state, error);
  ASSERT_TRUE(op) << error;
  EXPECT_EQ(op->mask, 0x6Fu);
  EXPECT_EQ(op->value, 0x27);
  EXPECT_EQ(op->within, 2s);

  // A hexadecimal placeholder written after 0x is the same whole value.
  const auto hex = compile_ok("write controlword 0x{value:X}", model.get());
  ASSERT_TRUE(hex);
  const std::vector<int64_t> word{0x1F};
  EXPECT_EQ(hex->with(word, error).value_or(Operation{}).value, 0x1F);

  const auto nmt = compile_ok("nmt reset-communication", nullptr);
  ASSERT_TRUE(nmt);
  EXPECT_EQ(nmt->operation().kind, Operation::Kind::nmt);
  EXPECT_EQ(nmt->operation().nmt, NmtCommand::reset_communication);
}

TEST(CompiledOperation, AValueOutsideTheObjectIsRefusedWhenFilledIn) {
  const auto model = drive_model();
  const auto write = compile_ok("write controlword {value}", model.get());
  ASSERT_TRUE(write);
  std::string error;
  const std::vector<int64_t> too_big{70000};
  EXPECT_FALSE(write->with(too_big, error));
  EXPECT_EQ(error, "value 70000 does not fit UNSIGNED16 (range 0..65535)");
  const std::vector<int64_t> none;
  EXPECT_FALSE(write->with(none, error));
  EXPECT_EQ(error, "0 values for 1 placeholders");
}

TEST(CompiledOperation, APlaceholderAnywhereElseDoesNotCompile) {
  const auto model = drive_model();
  const std::string whole =
      " must stand for the whole value written or waited for (or a wait's mask)";
  EXPECT_EQ(compile_error("write 0x{index:X}:0 UNSIGNED16 5", nullptr), "{index}" + whole);
  EXPECT_EQ(compile_error("write controlword 1{value}", model.get()), "{value}" + whole);
  EXPECT_EQ(compile_error("write 0x2000:0 VISIBLE_STRING \"{value}\"", nullptr), "{value}" + whole);
  EXPECT_EQ(compile_error("write controlword {value}0", model.get()), "{value}" + whole);
  EXPECT_EQ(compile_error("write controlword 0x{value}", model.get()), "{value}" + whole);
  EXPECT_EQ(compile_error("write controlword {value:X}", model.get()), "{value}" + whole);
  EXPECT_EQ(compile_error("wait statusword == 5 within {a}ms", model.get()), "{a}" + whole);
  EXPECT_EQ(compile_error("write controlword {a}{b}", model.get()), "{a}" + whole);
  EXPECT_EQ(compile_error("wait statusword & 3 == {a} within {b} s", model.get()),
            "wait: '0' is not a duration (e.g. 500ms, 2s)");
}

TEST(Request, WriteErrors) {
  const auto model = drive_model();
  EXPECT_EQ(parse_error("write 0x2001:0 5", model.get()),
            "no data type for 0x2001:0: write it after the object (e.g. 0x2001:0 UNSIGNED16) or "
            "declare the object on a point");
  EXPECT_EQ(parse_error("write controlword 70000", model.get()),
            "value 70000 does not fit UNSIGNED16 (range 0..65535)");
  EXPECT_EQ(parse_error("write modes_of_operation -129", model.get()),
            "value -129 does not fit INTEGER8 (range -128..127)");
  EXPECT_EQ(parse_error("write controlword", model.get()), "write: the value is missing");
  EXPECT_EQ(parse_error("write controlword six", model.get()),
            "write value: expected an integer, found 'six'");
  EXPECT_EQ(parse_error("write nosuch 1", model.get()),
            "'nosuch' is neither INDEX:SUB (such as 0x6040:0) nor a point of the model");
  EXPECT_EQ(parse_error("write 0x6040 1", model.get()),
            "'0x6040' is neither INDEX:SUB (such as 0x6040:0) nor a point of the model");
  EXPECT_EQ(parse_error("write 0x16040:0 1", model.get()),
            "expected INDEX:SUB such as 0x6040:0, found '0x16040:0'");
  EXPECT_EQ(parse_error("write controlword INTEGER32 1", model.get()),
            "point 'controlword' is UNSIGNED16, not INTEGER32");
  EXPECT_EQ(parse_error("write 0x2000:0 VISIBLE_STRING axis", nullptr),
            "VISIBLE_STRING takes a quoted string, found 'axis'");
  EXPECT_EQ(parse_error("write 0x2000:0 VISIBLE_STRING \"axis", nullptr),
            "unterminated string (a closing \" is missing)");
  EXPECT_EQ(parse_error("write controlword 1 2", model.get()), "unexpected '2' at the end");
  EXPECT_NE(parse_error("s r0x24 1", model.get()).find("unknown request 's'"), std::string::npos);
  EXPECT_NE(parse_error("", model.get()).find("expected 'read OBJECT'"), std::string::npos);
}

TEST(Request, ReadWaitNmt) {
  const auto model = drive_model();
  auto op = parse_ok("read 0x1008:0 VISIBLE_STRING", nullptr);
  EXPECT_EQ(op.kind, Operation::Kind::read);
  op = parse_ok("wait statusword & 0x6F == 0x27 within 1s", model.get());
  EXPECT_EQ(op.kind, Operation::Kind::wait);
  EXPECT_EQ(op.object.index, 0x6041);
  EXPECT_EQ(op.mask, 0x6Fu);
  EXPECT_EQ(op.value, 0x27);
  EXPECT_EQ(op.within, 1s);
  op = parse_ok("wait 0x6041:0 == 0x0250", model.get());
  EXPECT_EQ(op.mask, ~uint64_t{0});
  EXPECT_EQ(op.within, 2s);  // the default
  EXPECT_EQ(parse_error("wait statusword & 0x6F 0x27", model.get()),
            "wait: expected '== VALUE' (e.g. wait statusword & 0x6F == 0x27)");
  EXPECT_EQ(parse_error("wait statusword == 1 within", model.get()),
            "wait: a duration must follow 'within' (e.g. within 2s)");
  EXPECT_EQ(parse_error("wait statusword == 1 within soon", model.get()),
            "wait: 'soon' is not a duration (e.g. 500ms, 2s)");
  EXPECT_EQ(parse_error("wait 0x1008:0 VISIBLE_STRING == 1", nullptr),
            "wait needs an integer object, not VISIBLE_STRING");
  EXPECT_EQ(parse_ok("nmt reset", nullptr).nmt, NmtCommand::reset_node);
  EXPECT_EQ(parse_ok("nmt pre-operational", nullptr).nmt, NmtCommand::enter_pre_operational);
  EXPECT_EQ(parse_ok("nmt reset-communication", nullptr).nmt, NmtCommand::reset_communication);
  EXPECT_EQ(parse_error("nmt reboot", nullptr),
            "nmt: unknown command 'reboot' (expected start, stop, pre-operational, reset or "
            "reset-communication)");
}

PointDef point(ValueType type, std::optional<ObjectRef> object, std::string request = "",
               int field = 0) {
  PointDef p;
  p.name = "p";
  p.type = type;
  ReadSpec r;
  std::string error;
  r.request = *CommandTemplate::compile(request, error);
  r.object = std::move(object);
  r.field = field;
  p.read = r;
  return p;
}

TEST(PointSource, Kinds) {
  std::string error;
  auto src = compile_point_read(point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"}), error);
  ASSERT_TRUE(src) << error;
  EXPECT_EQ(src->kind, PointSource::Kind::sdo);
  src = compile_point_read(
      point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"}, "tpdo 0x180+id byte 2"), error);
  ASSERT_TRUE(src) << error;
  EXPECT_EQ(src->kind, PointSource::Kind::tpdo);
  EXPECT_EQ(src->tpdo.cob_for(5), 0x185u);
  EXPECT_EQ(src->tpdo.offset, 2);
  src = compile_point_read(point(ValueType::uint16, std::nullopt, "tpdo 0x2A5 byte 6 UNSIGNED16"),
                           error);
  ASSERT_TRUE(src) << error;
  EXPECT_FALSE(src->object);
  EXPECT_EQ(src->tpdo.cob_for(5), 0x2A5u);
  src = compile_point_read(point(ValueType::uint32, std::nullopt, "sdo abort"), error);
  ASSERT_TRUE(src) << error;
  EXPECT_EQ(src->kind, PointSource::Kind::local);
  EXPECT_EQ(src->local, LocalValue::sdo_abort);
}

TEST(PointSource, Errors) {
  const auto fails = [](PointDef p) {
    std::string error;
    EXPECT_FALSE(compile_point_read(p, error));
    return error;
  };
  EXPECT_EQ(fails(point(ValueType::int16, ObjectRef{0x6064, 0, "INTEGER32"})),
            "INTEGER32 does not fit a int16 point (use a wider type)");
  EXPECT_EQ(fails(point(ValueType::int32, ObjectRef{0x6064, 0, "INT32"})).substr(0, 27),
            "unknown data type 'INT32' (");
  EXPECT_EQ(fails(point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"}, "tpdo 0x180+id")),
            "expected 'tpdo COB-ID byte N' such as 'tpdo 0x180+id byte 2' or 'tpdo 0x1A5 byte 0'");
  EXPECT_EQ(
      fails(point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"}, "tpdo 0x180+id byte 6")),
      "INTEGER32 at byte 6 does not fit an 8-byte PDO");
  EXPECT_EQ(
      fails(point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"}, "tpdo 0x580+id byte 0")),
      "COB-ID 0x580+id is not usable for a TPDO (allowed 0x181..0x57F and 0x680..0x6DF "
      "for every node ID)");
  EXPECT_EQ(fails(point(ValueType::int32, std::nullopt, "tpdo 0x181 byte 0")),
            "tpdo: give the data type, after the byte offset or as the point's object");
  EXPECT_EQ(fails(point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"},
                        "tpdo 0x181 byte 0 INTEGER16")),
            "tpdo: the request says INTEGER16, the object INTEGER32");
  EXPECT_EQ(fails(point(ValueType::uint16, ObjectRef{0x1001, 0, "UNSIGNED8"}, "emcy code")),
            "'emcy code' is kept by the gateway, so the point takes no object");
  EXPECT_NE(fails(point(ValueType::uint16, std::nullopt, "g r0x32")).find("unknown read request"),
            std::string::npos);
  EXPECT_NE(
      fails(point(ValueType::int32, ObjectRef{0x1008, 0, "VISIBLE_STRING"})).find("must be uint16"),
      std::string::npos);
  EXPECT_EQ(fails(point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"}, "", 1)),
            "field applies only to string objects (VISIBLE_STRING, OCTET_STRING)");
}

TEST(PointValue, IntegersStringsAndPdos) {
  std::string error;
  auto src = *compile_point_read(point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"}), error);
  const uint8_t pos[] = {0x30, 0xF8, 0xFF, 0xFF};
  EXPECT_EQ(decode_point_value(src, ValueType::int32, pos, error), -2000);
  EXPECT_FALSE(decode_point_value(src, ValueType::int32, std::span(pos, 2), error));
  EXPECT_EQ(error, "INTEGER32 needs 4 bytes, 2 arrived");

  const std::string name = "fieldgate sim";
  const std::vector<uint8_t> text(name.begin(), name.end());
  auto s1 = *compile_point_read(
      point(ValueType::uint32, ObjectRef{0x1008, 0, "VISIBLE_STRING"}, "", 1), error);
  EXPECT_EQ(decode_point_value(s1, ValueType::uint32, text, error), 0x64676174);  // "dgat"
  auto s3 = *compile_point_read(
      point(ValueType::uint32, ObjectRef{0x1008, 0, "VISIBLE_STRING"}, "", 3), error);
  EXPECT_EQ(decode_point_value(s3, ValueType::uint32, text, error), 0x6D000000);  // "m", padded
  auto s2 = *compile_point_read(
      point(ValueType::uint16, ObjectRef{0x1008, 0, "VISIBLE_STRING"}, "", 2), error);
  EXPECT_EQ(decode_point_value(s2, ValueType::uint16, text, error), 0x6467);  // "dg"

  auto pdo = *compile_point_read(
      point(ValueType::int32, ObjectRef{0x6064, 0, "INTEGER32"}, "tpdo 0x180+id byte 2"), error);
  EXPECT_EQ(decode_tpdo_value(pdo, *parse_frame("182#3706D0070000"), error), 2000);
  EXPECT_FALSE(decode_tpdo_value(pdo, *parse_frame("182#370600"), error));
  EXPECT_EQ(error, "PDO 0x182 has 3 bytes, the model maps INTEGER32 up to byte 6");
}

}  // namespace
}  // namespace fieldgate::canopen
