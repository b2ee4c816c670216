// Issue 20 item 3 (Copley): where the ASCII guide allows several readings, the simulator can
// present each (switches) and the core read + move scenario runs under each:
//  - `v 1200` or `v1200` (§2.8 vs elsewhere);
//  - the prefix `0 ` addressing the gateway, refused (e 31) or forwarded to nobody (e 32);
//  - a command without axis letter to a multi-axis amplifier: axis a, e 33 or silence, with the
//    amplifier at its power-up rate so that the §4.1 baud switch must work under each.
// And issue 12 item 6: a node configured without the axis letter its amplifier needs is
// faulted (e 33) or offline (silence), never online.
#include <gtest/gtest.h>

#include <ostream>
#include <thread>

#include "harness.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

constexpr int kPosition = 0;
constexpr int kCommand = 100, kActionStatus = 101;
constexpr int kSetpointTarget = 110;
constexpr int kDiagLastDeviceError = 1010, kDiagNodeState = 1014;
constexpr int kEnable = 1, kMoveAbsolute = 3;

struct Reading {
  const char* name;
  std::vector<std::string> sim_switches;
  const char* nodes;  // config
};

// Without it GoogleTest prints the bytes, pointers among them, into the ctest name.
void PrintTo(const Reading& r, std::ostream* os) {
  for (const auto& s : r.sim_switches) *os << (&s == &r.sim_switches.front() ? "" : " ") << s;
}

SimulatedBus copley_bus(const Reading& r) {
  SimulatedBus bus;
  bus.name = "copley";
  bus.protocol = "copley-ascii";
  bus.sim_argv = {FIELDGATE_SIM_COPLEY, "--link", "{link}"};
  for (const auto& s : r.sim_switches) bus.sim_argv.push_back(s);
  bus.nodes = r.nodes;
  return bus;
}

const char* kTwoNodes =
    "      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1}\n"
    "      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2}\n";
const char* kTwoAxes =
    "      - {name: x, address: 0.a, model: copley-amplifier, unit_id: 1}\n"
    "      - {name: y, address: 0.b, model: copley-amplifier, unit_id: 2}\n";

class CopleyReadings : public ::testing::TestWithParam<Reading> {};

TEST_P(CopleyReadings, CoreReadAndMoveScenario) {
  Plant plant({copley_bus(GetParam())});
  ModbusClient client("127.0.0.1", plant.port());
  for (int unit : {1, 2})
    ASSERT_TRUE(wait_until([&] { return client.read_input(unit, kPosition, 2).ok(); }, 20s))
        << "unit " << unit << " never came online\n"
        << plant.daemon().log();
  for (int unit : {1, 2}) EXPECT_EQ(client.read_input_i32(unit, kPosition), 0);
  // Move unit 2, then unit 1, to distinct targets; each ends where it was sent.
  for (const auto& [unit, target] : {std::pair{2, 4000}, std::pair{1, -2500}}) {
    ASSERT_TRUE(client.write_i32(unit, kSetpointTarget, target).ok());
    ASSERT_TRUE(client.write_single(unit, kCommand, kEnable).ok()) << plant.daemon().log();
    ASSERT_TRUE(client.write_single(unit, kCommand, kMoveAbsolute).ok()) << plant.daemon().log();
    ASSERT_TRUE(wait_until(
        [&, unit = unit] {
          auto r = client.read_holding(unit, kActionStatus, 1);
          return r.ok() && r.values[0] == 2;
        },
        20s))
        << "unit " << unit << "\n"
        << plant.daemon().log();
    EXPECT_EQ(client.read_input_i32(unit, kPosition), target) << "unit " << unit;
  }
  EXPECT_EQ(client.read_input_i32(2, kPosition), 4000);
}

INSTANTIATE_TEST_SUITE_P(
    Manual, CopleyReadings,
    ::testing::Values(
        Reading{"spaced_replies", {"--nodes", "0,3"}, kTwoNodes},
        Reading{"compact_replies", {"--nodes", "0,3", "--compact-replies"}, kTwoNodes},
        Reading{"zero_prefix_refused", {"--nodes", "0,3", "--zero-prefix", "e31"}, kTwoNodes},
        Reading{"zero_prefix_forwarded", {"--nodes", "0,3", "--zero-prefix", "e32"}, kTwoNodes},
        Reading{"missing_axis_goes_to_a",
                {"--axes", "2", "--missing-axis", "a", "--baud", "9600"},
                kTwoAxes},
        Reading{"missing_axis_e33",
                {"--axes", "2", "--missing-axis", "e33", "--baud", "9600"},
                kTwoAxes},
        Reading{"missing_axis_silent",
                {"--axes", "2", "--missing-axis", "silent", "--baud", "9600"},
                kTwoAxes}),
    [](const auto& info) { return std::string(info.param.name); });

// A 2-axis amplifier configured as plain node 0 (no axis letter).
class CopleyMissingAxisLetter : public ::testing::TestWithParam<const char*> {};

TEST_P(CopleyMissingAxisLetter, NodeIsNeverOnlineUnlessTheAmplifierTakesAxisA) {
  const std::string reading = GetParam();
  Reading r{"",
            {"--axes", "2", "--missing-axis", reading},
            "      - {name: amp, address: 0, model: copley-amplifier, unit_id: 1}\n"};
  Plant plant({copley_bus(r)});
  ModbusClient client("127.0.0.1", plant.port());
  auto state = [&] {
    auto d = client.read_input(1, kDiagNodeState, 1);
    return d.ok() ? d.values[0] : -1;
  };
  if (reading == "a") {
    EXPECT_TRUE(wait_until([&] { return state() == 1; }, 10s));
    return;
  }
  const int expected = reading == "e33" ? 3 : 2;  // faulted : offline
  ASSERT_TRUE(wait_until([&] { return state() == expected; }, 10s)) << "state " << state() << "\n"
                                                                    << plant.daemon().log();
  // It stays so: never online in between or after.
  for (int i = 0; i < 10; ++i) {
    std::this_thread::sleep_for(50ms);
    EXPECT_EQ(state(), expected);
  }
  EXPECT_EQ(client.read_input(1, kPosition, 2).exception, 0x0B);
  const std::string log = plant.daemon().log();
  EXPECT_EQ(log.find("node amp (0) online"), std::string::npos) << log;
  if (reading == "e33") {
    EXPECT_EQ(client.read_input(1, kDiagLastDeviceError, 1).values, std::vector<uint16_t>{33});
    EXPECT_NE(log.find("node amp (0) faulted"), std::string::npos) << log;
    EXPECT_NE(log.find("e 33"), std::string::npos) << log;
  }
}

INSTANTIATE_TEST_SUITE_P(Manual, CopleyMissingAxisLetter, ::testing::Values("a", "e33", "silent"),
                         [](const auto& info) { return std::string(info.param); });

}  // namespace
}  // namespace fieldgate::test
