#include <gtest/gtest.h>

#include "mapping/model_loader.hpp"
#include "mapping/register_map.hpp"

namespace fieldgate {
namespace {

ModelPtr load(const std::string& text) {
  Diagnostics d;
  auto m = load_model_text(text, "m.yaml", d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  return m;
}

const char* kModel = R"(model: m
family: copley-ascii
poll_classes: {fast: 100ms}
points:
  position: {type: int32, read: g r0x32, poll: fast}
  status: {type: uint32, read: g r0xa0, poll: fast, bits: {moving: 27, fault: 22}}
  state: {type: int16, read: g r0x24, write: "s r0x24 {value}", poll: fast}
  target: {type: int32, write: "s r0xca {value}"}
setpoints:
  speed: {type: int32, default: 5}
actions:
  go: {code: 3, steps: [t 1]}
)";

TEST(RegisterMap, LayoutFollowsTheModel) {
  Diagnostics d;
  auto map = RegisterMap::build({{7, 0, "x", "bus", load(kModel)}}, WordOrder::high_first, d);
  ASSERT_TRUE(d.ok()) << d.to_text();
  const UnitMap* unit = map.unit(7);
  ASSERT_TRUE(unit);
  EXPECT_FALSE(map.unit(8));
  // Read-only points: input registers from 0, 32-bit values take two.
  auto* e = unit->find(Table::input_registers, 0);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->name, "position");
  EXPECT_EQ(unit->find(Table::input_registers, 1), e);
  EXPECT_EQ(unit->find(Table::input_registers, 2)->name, "status");
  EXPECT_FALSE(unit->find(Table::input_registers, 4));
  // Writable points: holding registers from 0.
  EXPECT_EQ(unit->find(Table::holding_registers, 0)->name, "state");
  EXPECT_EQ(unit->find(Table::holding_registers, 1)->name, "target");
  EXPECT_EQ(unit->find(Table::holding_registers, 2)->name, "target");
  // Status bits: discrete inputs.
  EXPECT_EQ(unit->find(Table::discrete_inputs, 0)->name, "status.moving");
  EXPECT_EQ(unit->find(Table::discrete_inputs, 1)->bit, 22);
  // Fixed places.
  EXPECT_EQ(unit->find(Table::holding_registers, layout::action_block)->kind,
            RegisterEntry::Kind::action_command);
  EXPECT_EQ(unit->find(Table::holding_registers, layout::action_block + 1)->kind,
            RegisterEntry::Kind::action_status);
  EXPECT_EQ(unit->find(Table::holding_registers, layout::setpoints)->name, "speed");
  EXPECT_EQ(unit->find(Table::input_registers, layout::diagnostics)->name, "diag.online");
  EXPECT_EQ(unit->find(Table::input_registers, layout::diagnostics + 1)->name,
            "diag.last_good_age");
  EXPECT_EQ(unit->find(Table::discrete_inputs, layout::online_bit)->name, "diag.online");
  EXPECT_FALSE(unit->find(Table::coils, 0));
}

TEST(RegisterMap, TooManyWritablePointsIsAnError) {
  std::string text = "model: big\nfamily: copley-ascii\npoints:\n";
  for (int i = 0; i < 51; ++i)
    text += "  p" + std::to_string(i) + ": {type: int32, write: \"s r0x1 {value}\"}\n";
  Diagnostics d;
  RegisterMap::build({{1, 0, "x", "bus", load(text)}}, WordOrder::high_first, d);
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.errors().front().message.find("102 holding registers"), std::string::npos)
      << d.to_text();
}

}  // namespace
}  // namespace fieldgate
