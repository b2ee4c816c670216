// The real daemon against fieldgate-sim-centent on a PTY, through Modbus TCP (libmodbus).
#include <gtest/gtest.h>

#include <iostream>
#include <random>
#include <regex>
#include <thread>

#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// Register layout of config/models/centent-cn0170.yaml.
constexpr int kXPosition = 0, kMotion = 4, kResets = 14, kOverflowWarnings = 16, kQueueFull = 17,
              kChainPosition = 23;                                      // input registers
constexpr int kXProfile = 2, kOut1 = 4;                                 // holding registers
constexpr int kCommand = 100, kActionStatus = 101, kActionError = 102;  // action block
constexpr int kXTarget = 110, kXDistance = 114, kXSpeed = 118, kXResolution = 125;  // setpoints
constexpr int kDiagLastGoodAge = 1001, kDiagNodeState = 1014;
constexpr int kMoveXAbsolute = 1, kMoveXRelative = 2, kHomeX = 7, kQuit = 10, kKill = 12,
              kJogXCw = 15;
constexpr int kXMovingBit = 0, kMovingBit = 4;
constexpr int kIllegalValue = 0x03, kDeviceFailure = 0x04, kTargetFailed = 0x0B;

std::string nodes(const std::vector<int>& units, const std::string& poll) {
  std::string out;
  for (int u : units)
    out += "      - {name: cn" + std::to_string(u) + ", address: " + std::to_string(u) +
           ", model: centent-cn0170, unit_id: " + std::to_string(u + 1) + poll + "}\n";
  return out;
}

class CententPlant : public Plant {
 public:
  CententPlant(const std::string& sim_units, const std::string& config_nodes,
               std::vector<std::string> extra = {}, const std::string& baud = "115200")
      : Plant({SimulatedBus{"chain", "centent-cn0170", argv(sim_units, std::move(extra)),
                            "baud: " + baud,
                            "reply_timeout: 50ms, byte_timeout: 10ms, retries: 1, "
                            "offline_after: 3, probe_interval: 300ms",
                            config_nodes}}) {}

  // A control command to the simulator; returns its "ok …" reply line.
  std::string control(const std::string& command) {
    const std::string verb = command.substr(0, command.find(' '));
    const auto count = [&] {
      const std::string log = sim().log();
      std::size_t n = 0;
      for (auto p = log.find("ok " + verb); p != std::string::npos;
           p = log.find("ok " + verb, p + 1))
        ++n;
      return n;
    };
    const std::size_t before = count();
    sim().send_line(command);
    if (!wait_until([&] { return count() > before; }, 5s)) return "no reply";
    const std::string log = sim().log();
    const auto at = log.rfind("ok " + verb);
    return log.substr(at, log.find('\n', at) - at);
  }
  uint64_t stat(const std::string& command, const std::string& key) {
    const std::string line = control(command);
    std::smatch m;
    if (!std::regex_search(line, m, std::regex(" " + key + "=([0-9]+)"))) return ~0ull;
    return std::stoull(m[1]);
  }

 private:
  static std::vector<std::string> argv(const std::string& units, std::vector<std::string> extra) {
    std::vector<std::string> a{FIELDGATE_SIM_CENTENT, "--link", "{link}", "--units", units};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
};

class CententEndToEnd : public PlantFixture<::testing::Test, CententPlant> {
 protected:
  void start(const std::string& sim_units, const std::vector<int>& units,
             const std::string& poll = ", poll: {fast: 100ms, slow: 1s}",
             std::vector<std::string> extra = {}, const std::string& baud = "115200") {
    PlantFixture::start(
        std::make_unique<CententPlant>(sim_units, nodes(units, poll), std::move(extra), baud));
  }
  void wait_online(const std::vector<int>& unit_ids) { wait_inputs(unit_ids, kXPosition, 5); }
  int action_status(int id) { return holding(id, kActionStatus); }
  std::optional<uint32_t> age_ms(int id) {
    auto r = client_->read_input(id, kDiagLastGoodAge, 2);
    if (!r.ok()) return std::nullopt;
    return (static_cast<uint32_t>(r.values[0]) << 16) | r.values[1];
  }
  int motion(int id) { return input(id, kMotion); }
};

TEST_F(CententEndToEnd, BothAxesOfThreeUnitsPerCycleWithOneSelectionEach) {
  // A 100 ms cycle reads X and Y of the three units (one line per unit); the slow class is
  // pushed out of the way (one status read per unit at start).
  start("0,1,2", {0, 1, 2}, ", poll: {fast: 100ms, slow: 3600s}");
  wait_online({1, 2, 3});
  for (int id : {1, 2, 3}) {
    auto r = client_->read_input(id, kXPosition, 5);  // X, Y, motion word
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r.values, (std::vector<uint16_t>{0, 0, 0, 0, 0}));
  }
  std::this_thread::sleep_for(500ms);  // past the first contact (mode check, M1\-)
  const uint64_t sel0 = plant_->stat("stats", "selections");
  const uint64_t lines0 = plant_->stat("stats 0", "lines");
  std::this_thread::sleep_for(3s);
  const uint64_t sel1 = plant_->stat("stats", "selections");
  const uint64_t lines1 = plant_->stat("stats 0", "lines");
  const double cycles = static_cast<double>(lines1 - lines0);
  const double per_cycle = static_cast<double>(sel1 - sel0) / cycles;
  std::cout << "[ measured ] " << cycles << " cycles, " << (sel1 - sel0)
            << " selections: " << per_cycle << " .Un per cycle of 3 units\n";
  RecordProperty("selections_per_cycle", std::to_string(per_cycle));
  EXPECT_GE(cycles, 20.0);
  EXPECT_NEAR(per_cycle, 3.0, 0.15) << "one selection per unit and cycle";
  // Positions of both axes of all three units are fresh.
  for (int id : {1, 2, 3}) EXPECT_LT(age_ms(id).value_or(~0u), 300u);
}

TEST_F(CententEndToEnd, DefaultScheduleSelectionCount) {
  start("0,1,2", {0, 1, 2}, "");
  wait_online({1, 2, 3});
  std::this_thread::sleep_for(2500ms);
  const uint64_t sel0 = plant_->stat("stats", "selections");
  const uint64_t lines0 = plant_->stat("stats 0", "lines");
  std::this_thread::sleep_for(4s);
  const uint64_t sel1 = plant_->stat("stats", "selections");
  const uint64_t lines1 = plant_->stat("stats 0", "lines");
  // Per 200 ms cycle unit 0 gets its position line; per 2 s its status line and M?.
  const double cycles = static_cast<double>(lines1 - lines0) / (1.0 + 2.0 / 10.0);
  const double per_cycle = static_cast<double>(sel1 - sel0) / cycles;
  std::cout << "[ measured ] default schedule: " << per_cycle
            << " .Un per 200 ms cycle (3 position lines + 0.6 slow lines per cycle)\n";
  RecordProperty("default_selections_per_cycle", std::to_string(per_cycle));
  // A slow line between two other units' position lines costs one extra selection at most.
  EXPECT_LE(per_cycle, 3.0 + 0.6 + 0.2);
  EXPECT_GE(per_cycle, 2.8);
}

TEST_F(CententEndToEnd, MoveOnUnit2WhileUnits0And1KeepUpdating) {
  start("0,1,2", {0, 1, 2});
  wait_online({1, 2, 3});
  ASSERT_TRUE(client_->write_single(2, kCommand, kJogXCw).ok());  // unit 1 runs at 500 steps/s
  ASSERT_TRUE(client_->write_i32(3, kXTarget, 3000 * 1024).ok());
  ASSERT_TRUE(client_->write_single(3, kCommand, kMoveXAbsolute).ok());
  EXPECT_EQ(action_status(3), 1);  // confirmed by the unit; the move is under way
  int32_t last2 = -1, last1 = -1;
  for (int i = 0; i < 6; ++i) {
    std::this_thread::sleep_for(200ms);
    const auto p2 = client_->read_input_i32(3, kXPosition);
    const auto p1 = client_->read_input_i32(2, kXPosition);
    ASSERT_TRUE(p2 && p1);
    EXPECT_GT(*p2, last2) << "unit 2 advances";
    EXPECT_GT(*p1, last1) << "unit 1 keeps updating";
    last2 = *p2;
    last1 = *p1;
    for (int id : {1, 2}) EXPECT_LT(age_ms(id).value_or(~0u), 400u) << "unit id " << id;
  }
  ASSERT_TRUE(wait_until([&] { return action_status(3) == 2; }, 10s));
  EXPECT_EQ(client_->read_input_i32(3, kXPosition), 3000 * 1024);
  EXPECT_EQ(motion(3) & (1 << kXMovingBit), 0);
  EXPECT_EQ(client_->read_input_i32(1, kXPosition), 0) << "unit 0 never moved";
  ASSERT_TRUE(client_->write_single(2, kCommand, kQuit).ok());
  ASSERT_TRUE(wait_until([&] { return action_status(2) == 2; }, 5s));
  // A negative relative move on unit 2 (signed distance, sent as X-…H).
  ASSERT_TRUE(client_->write_i32(3, kXDistance, -1024 * 1000).ok());
  ASSERT_TRUE(client_->write_single(3, kCommand, kMoveXRelative).ok());
  ASSERT_TRUE(wait_until([&] { return action_status(3) == 2; }, 10s));
  EXPECT_EQ(client_->read_input_i32(3, kXPosition), 2000 * 1024);
}

TEST_F(CententEndToEnd, MissingUnitGoesOfflineWithoutStallingTheChain) {
  start("0,1,2,4", {0, 1, 2, 3});
  wait_online({1, 2, 3});
  ASSERT_TRUE(wait_until([&] { return input(4, kDiagNodeState) == 2; }));
  EXPECT_EQ(client_->read_input(4, kXPosition, 2).exception, kTargetFailed);
  EXPECT_EQ(client_->write_single(4, kCommand, kMoveXAbsolute).exception, kTargetFailed);
  for (int i = 0; i < 5; ++i) {
    std::this_thread::sleep_for(200ms);
    for (int id : {1, 2, 3}) EXPECT_LT(age_ms(id).value_or(~0u), 400u) << "unit id " << id;
  }
  const std::string log = plant_->daemon().log();
  EXPECT_NE(log.find("chain order from .U?: 0, 1, 2, 4"), std::string::npos) << log;
  EXPECT_NE(log.find("unit 3 is configured but did not answer .U?"), std::string::npos) << log;
  EXPECT_NE(log.find("unit 4 is on the chain but not configured"), std::string::npos) << log;
  EXPECT_NE(log.find("node cn3 (3) offline"), std::string::npos) << log;
  ASSERT_TRUE(wait_until([&] { return client_->read_input(3, kChainPosition, 1).ok(); }, 5s));
  EXPECT_EQ(client_->read_input(1, kChainPosition, 1).values, std::vector<uint16_t>{1});
  EXPECT_EQ(client_->read_input(3, kChainPosition, 1).values, std::vector<uint16_t>{3});
}

TEST_F(CententEndToEnd, UnsolicitedResetResynchronisesTheSelection) {
  start("0,1,2", {0, 1, 2});
  wait_online({1, 2, 3});
  EXPECT_EQ(plant_->control("reset 1"), "ok reset 1");
  ASSERT_TRUE(wait_until([&] { return input(2, kResets) == 1; }, 5s));
  // Every unit answers again, with fresh positions.
  std::this_thread::sleep_for(500ms);
  for (int id : {1, 2, 3}) EXPECT_LT(age_ms(id).value_or(~0u), 400u) << "unit id " << id;
  // A move for unit 2 reaches unit 2, not the unit that reset (which selects itself).
  ASSERT_TRUE(client_->write_i32(3, kXDistance, 1024 * 100).ok());
  ASSERT_TRUE(client_->write_single(3, kCommand, kMoveXRelative).ok());
  ASSERT_TRUE(wait_until([&] { return action_status(3) == 2; }, 10s));
  EXPECT_EQ(client_->read_input_i32(3, kXPosition), 1024 * 100);
  EXPECT_EQ(client_->read_input_i32(2, kXPosition), 0);
  EXPECT_NE(plant_->control("position 1").find(" x=0 "), std::string::npos);
  const std::string log = plant_->daemon().log();
  EXPECT_NE(log.find("unit 1 reset (unsolicited 'U1')"), std::string::npos) << log;
}

TEST_F(CententEndToEnd, KillWrittenToAnyUnitStopsTheWholeChain) {
  start("0,1,2", {0, 1, 2});
  wait_online({1, 2, 3});
  for (int id : {1, 2, 3}) ASSERT_TRUE(client_->write_single(id, kCommand, kJogXCw).ok());
  ASSERT_TRUE(
      wait_until([&] { return (motion(1) & motion(2) & motion(3) & (1 << kMovingBit)) != 0; }, 3s));
  ASSERT_TRUE(client_->write_single(3, kCommand, kKill).ok());
  ASSERT_TRUE(wait_until([&] { return motion(1) == 0 && motion(2) == 0 && motion(3) == 0; }, 2s));
  EXPECT_EQ(plant_->stat("stats 0", "kills"), 1u) << "K went to the first unit";
  EXPECT_EQ(plant_->stat("stats 2", "kills"), 1u) << "and was relayed";
  EXPECT_NE(plant_->daemon().log().find("kill (K) sent from unit 0 down the chain"),
            std::string::npos);
}

TEST_F(CententEndToEnd, RefusalsAnswer04WithTheFamilyCode) {
  start("0,1", {0, 1});
  wait_online({1, 2});
  // XR accepts 1, 2, 10 or 125 only: refused before anything is sent.
  ASSERT_TRUE(client_->write_single(1, kXResolution, 3).ok());
  EXPECT_EQ(client_->write_single(1, kCommand, kHomeX).exception, kDeviceFailure);
  EXPECT_EQ(client_->read_holding(1, kActionError, 1).values, std::vector<uint16_t>{4});
  // Queue nearly full (Q*): moves are refused until *Q.
  plant_->control("emit 1 Q*");
  ASSERT_TRUE(wait_until([&] { return input(2, kQueueFull) == 1; }, 5s));
  EXPECT_EQ(client_->read_input(2, kOverflowWarnings, 1).values, std::vector<uint16_t>{1});
  EXPECT_EQ(client_->write_single(2, kCommand, kMoveXAbsolute).exception, kDeviceFailure);
  EXPECT_EQ(client_->read_holding(2, kActionError, 1).values, std::vector<uint16_t>{2});
  plant_->control("emit 1 *Q");
  ASSERT_TRUE(wait_until([&] { return input(2, kQueueFull) == 0; }, 5s));
  EXPECT_TRUE(client_->write_single(2, kCommand, kMoveXAbsolute).ok());
}

TEST_F(CententEndToEnd, AutobaudAtStartAndSettingsReadBack) {
  start("0,1", {0, 1}, ", poll: {fast: 100ms, slow: 200ms}");  // power-up state: the default
  wait_online({1, 2});
  EXPECT_NE(plant_->daemon().log().find("auto-baud CR answered by unit(s) 0, 1"),
            std::string::npos);
  ASSERT_TRUE(client_->write_single(2, kXProfile, 18).ok());  // sent as XC\P
  ASSERT_TRUE(client_->write_single(2, kOut1, 1).ok());
  EXPECT_NE(plant_->control("position 1").find("out1=1"), std::string::npos);
  ASSERT_TRUE(wait_until(
      [&] {
        auto r = client_->read_holding(2, kXProfile, 3);
        return r.ok() && r.values[0] == 18 && r.values[2] == 1;
      },
      3s));
  EXPECT_EQ(client_->write_single(2, kXProfile, 20).exception, 0x03);  // max 19
}

}  // namespace
}  // namespace fieldgate::test

// The core read+move scenario under each reading of the manual's reply formats (issue 20),
// from the units' power-up state (waiting for the auto-baud CR).
namespace fieldgate::test {
namespace {

struct Reading {
  const char* name;
  std::vector<std::string> sim_args;
};

std::ostream& operator<<(std::ostream& os, const Reading& r) {
  return os << r.name;
}

const Reading kReadings[] = {
    {"digit_x_cr", {}},
    {"space_xp_crlf",
     {"--prefix-separator", "space", "--position-reply", "xp", "--terminator", "crlf",
      "--prefix-unit-messages"}},
    {"colon_x_lf_plain_overflow",
     {"--prefix-separator", "colon", "--terminator", "lf", "--overflow-mnemonic", "plain"}},
    {"initialised_xp_cr", {"--initialised", "--position-reply", "xp"}},
};

class CententReadingEndToEnd : public CententEndToEnd,
                               public ::testing::WithParamInterface<Reading> {};

TEST_P(CententReadingEndToEnd, ReadsMovesAndReadsBack) {
  start("0,1,2", {0, 1, 2}, ", poll: {fast: 100ms, slow: 1s}", GetParam().sim_args);
  wait_online({1, 2, 3});
  ASSERT_TRUE(client_->write_i32(3, kXTarget, 1000 * 1024).ok());
  ASSERT_TRUE(client_->write_single(3, kCommand, kMoveXAbsolute).ok());
  ASSERT_TRUE(wait_until([&] { return action_status(3) == 2; }, 10s));
  EXPECT_EQ(client_->read_input_i32(3, kXPosition), 1000 * 1024);
  EXPECT_EQ(motion(3) & (1 << kMovingBit), 0);
  EXPECT_EQ(client_->read_input_i32(2, kXPosition), 0);
  EXPECT_EQ(client_->read_input_i32(1, kXPosition), 0);
}

INSTANTIATE_TEST_SUITE_P(Readings, CententReadingEndToEnd, ::testing::ValuesIn(kReadings),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate::test

// Replies slower than the reply timeout (issue 12), at 9600 baud with wire time and at 115200:
// every value served as good is that unit's, every output write answered success is on that
// unit.
namespace fieldgate::test {
namespace {

class CententLateEndToEnd : public CententEndToEnd,
                            public ::testing::WithParamInterface<const char*> {};

TEST_P(CententLateEndToEnd, NoWrongValueAndNoWrongConfirmation) {
  const std::string baud = GetParam();
  std::vector<std::string> extra{"--baud", baud};
  if (baud == "9600") extra.push_back("--emulate-wire");
  start("0,1,2", {0, 1, 2}, ", poll: {fast: 200ms, slow: 2s}", extra, baud);
  wait_online({1, 2, 3});
  ASSERT_TRUE(client_->write_i32(3, kXTarget, 1000 * 1024).ok());
  ASSERT_TRUE(client_->write_single(3, kCommand, kMoveXAbsolute).ok());
  ASSERT_TRUE(wait_until([&] { return action_status(3) == 2; }, 20s));
  const int32_t positions[] = {0, 0, 1000 * 1024};
  std::mt19937 random(3);
  const int delays[] = {0, 20, 40, 60, 90, 150};
  int good = 0, wrong = 0, writes_ok = 0, writes_wrong = 0;
  const auto until = std::chrono::steady_clock::now() + 5s;
  while (std::chrono::steady_clock::now() < until) {
    plant_->sim().send_line("delay " + std::to_string(delays[random() % std::size(delays)]));
    const int id = 1 + static_cast<int>(random() % 3);
    if (random() % 6 == 0) {
      const int on = static_cast<int>(random() % 2);
      if (client_->write_single(id, kOut1, on).ok()) {
        ++writes_ok;
        const std::string status = plant_->control("position " + std::to_string(id - 1));
        if (status.find(" out1=" + std::to_string(on)) == std::string::npos) {
          ++writes_wrong;
          ADD_FAILURE() << "out1=" << on << " confirmed on unit " << id - 1 << ": " << status;
        }
      }
      continue;
    }
    const auto value = client_->read_input_i32(id, kXPosition);
    std::this_thread::sleep_for(std::chrono::milliseconds(random() % 20));
    if (!value) continue;
    ++good;
    if (*value != positions[id - 1]) {
      ++wrong;
      ADD_FAILURE() << "unit " << id - 1 << " served " << *value;
    }
  }
  plant_->sim().send_line("delay 0");
  std::cout << "[ measured ] " << baud << ": " << good << " good reads, " << wrong << " wrong; "
            << writes_ok << " writes confirmed, " << writes_wrong << " wrong\n";
  EXPECT_GT(good, 0);
  wait_online({1, 2, 3});
}

INSTANTIATE_TEST_SUITE_P(Bauds, CententLateEndToEnd, ::testing::Values("9600", "115200"));

// README "Try it" writes a negative value to holding 110 with `-- -4000`; on unit 22 that was
// an absolute move across 0. The CN0170's positions are "positive only" (§9 #20): a unit that
// compares them unsigned (the simulator's default) ran the long way round the register, busy
// for 35 minutes, and every later move queued behind it. A negative target is refused (0x03),
// and from below 0 a positive one (0x04, code 4); relative moves go below 0.
class CententPositionSign : public CententEndToEnd,
                            public ::testing::WithParamInterface<std::string> {};

TEST_P(CententPositionSign, AbsoluteMoveAcrossZeroIsRefusedRelativeGoesBelow) {
  start("0,1,2", {0, 1, 2}, ", poll: {fast: 100ms, slow: 1s}", {"--absolute-compare", GetParam()});
  wait_online({1, 2, 3});
  const int id = 2;  // unit 1, Modbus unit ID 2 here (22 in the demo)
  const auto run = [&](int setpoint, int32_t value, int command) {
    EXPECT_TRUE(client_->write_i32(id, setpoint, value).ok());
    const int exception = client_->write_single(id, kCommand, command).exception;
    EXPECT_TRUE(wait_until([&] { return action_status(id) != 1; }, 30s))
        << "action stuck busy, x_position " << client_->read_input_i32(id, kXPosition).value_or(-1);
    return exception;
  };
  // A negative target cannot even be written: the model's minimum is 0 (and the codec refuses
  // one a model lets through).
  EXPECT_EQ(client_->write_i32(id, kXTarget, -4000).exception, kIllegalValue);
  EXPECT_NE(plant_->control("position 1").find("x=0 "), std::string::npos)
      << plant_->control("position 1");
  // The second move of the report: it runs and ends.
  EXPECT_EQ(run(kXTarget, 3000, kMoveXAbsolute), 0);
  EXPECT_EQ(action_status(id), 2);
  EXPECT_EQ(client_->read_input_i32(id, kXPosition), 3000);
  // Below 0 by a relative move; an absolute move from there to a positive target crosses 0 and
  // is refused (0x04, code 4) whichever reading the unit has.
  EXPECT_EQ(run(kXDistance, -7000, kMoveXRelative), 0);
  EXPECT_EQ(client_->read_input_i32(id, kXPosition), -4000);
  EXPECT_EQ(run(kXTarget, 3000, kMoveXAbsolute), kDeviceFailure);
  EXPECT_EQ(action_status(id), 3);
  EXPECT_EQ(client_->read_holding(id, kActionError, 1).values, std::vector<uint16_t>{4});
  EXPECT_EQ(client_->read_input_i32(id, kXPosition), -4000);
  EXPECT_EQ(run(kXDistance, 7000, kMoveXRelative), 0);
  EXPECT_EQ(client_->read_input_i32(id, kXPosition), 3000);
}

INSTANTIATE_TEST_SUITE_P(Readings, CententPositionSign, ::testing::Values("unsigned", "signed"));

// Seen on the demo under load: one poll whose Y reply was cut or lost left it owed, and every
// later poll took its own Y reply for the late one and was garbled in turn, so the motion word
// was never read again and the move stayed busy. One poll that loses its Y reply costs that poll
// (and at most the write-off window), and the move ends done where it should.
TEST_F(CententEndToEnd, LostReplyLinesDuringAMoveDoNotKeepItBusy) {
  start("1", {1}, ", poll: {fast: 100ms, slow: 3600s}");
  wait_online({2});
  const int id = 2;
  ASSERT_TRUE(client_->write_single(id, kXSpeed, 500).ok());  // 3000 steps: 6 s
  ASSERT_TRUE(client_->write_i32(id, kXTarget, 3000 * 1024).ok());
  ASSERT_TRUE(client_->write_single(id, kCommand, kMoveXAbsolute).ok());
  for (int i = 0; i < 3; ++i) {
    std::this_thread::sleep_for(1s);
    plant_->control("drop-last-line 1");  // the next poll gets "1X+…h\r" alone
  }
  ASSERT_TRUE(wait_until([&] { return action_status(id) != 1; }, 60s));
  EXPECT_EQ(action_status(id), 2) << "error "
                                  << client_->read_holding(id, kActionError, 1).values.at(0);
  EXPECT_EQ(client_->read_input_i32(id, kXPosition), 3000 * 1024);
  EXPECT_EQ(plant_->daemon().log().find("its end cannot be seen"), std::string::npos);
}

// Garbled replies leave a node online, so polls that keep coming back garbled never take it
// offline; an action watching them stayed busy until its timeout (30 minutes for a move). It
// fails once its condition point has gone unread for twenty poll periods (at least 15 s).
TEST_F(CententEndToEnd, PersistentGarbledPollsFailAWatchedMoveInBoundedTime) {
  start("0,1", {0, 1});
  wait_online({1, 2});
  const int id = 2;
  ASSERT_TRUE(client_->write_single(id, kXSpeed, 10).ok());  // 3000 steps: 300 s
  ASSERT_TRUE(client_->write_i32(id, kXTarget, 3000 * 1024).ok());
  ASSERT_TRUE(client_->write_single(id, kCommand, kMoveXAbsolute).ok());
  ASSERT_TRUE(wait_until([&] { return (motion(id) >> kXMovingBit & 1) == 1; }, 5s));
  plant_->control("garbage 1000000");
  ASSERT_TRUE(wait_until([&] { return action_status(id) != 1; }, 60s))
      << "still busy while every poll is garbled";
  EXPECT_EQ(action_status(id), 3);
  const uint16_t error = client_->read_holding(id, kActionError, 1).values.at(0);
  EXPECT_TRUE(error == 0xfffb || error == 0xfffd) << error;
  EXPECT_NE(plant_->daemon().log().find("its end cannot be seen"), std::string::npos);
}

// Repeated moves of one axis, as in README "Try it": out, back to 0, again to 0 (no distance),
// a relative move of 0, then out again. A move that starts and ends where the axis is never
// shows "moving"; each action must still end (done), and the next one must run.
class CententRepeatedMoves : public CententEndToEnd,
                             public ::testing::WithParamInterface<std::string> {};

TEST_P(CententRepeatedMoves, EveryMoveEndsIncludingZeroDistance) {
  const std::string baud = GetParam();
  std::vector<std::string> extra;
  if (baud == "9600") extra = {"--emulate-wire", "--hop-delay-us", "500"};  // as scripts/demo
  start("0,1,2", {0, 1, 2}, "", std::move(extra), baud);
  wait_online({1, 2, 3});
  const int id = 2;  // unit 1
  struct Move {
    int command;
    int setpoint;
    int32_t value;
    int32_t expected_position;
  };
  const std::vector<Move> moves{{kMoveXAbsolute, kXTarget, 3000, 3000},
                                {kMoveXAbsolute, kXTarget, 0, 0},
                                {kMoveXAbsolute, kXTarget, 0, 0},
                                {kMoveXRelative, kXDistance, 0, 0},
                                {kMoveXAbsolute, kXTarget, 3000, 3000},
                                {kMoveXAbsolute, kXTarget, 3000, 3000},
                                {kMoveXAbsolute, kXTarget, 0, 0},
                                {kMoveXAbsolute, kXTarget, 3000 * 1024, 3000 * 1024},
                                {kMoveXAbsolute, kXTarget, 3000 * 1024, 3000 * 1024},
                                {kMoveXAbsolute, kXTarget, 0, 0}};
  for (std::size_t i = 0; i < moves.size(); ++i) {
    const Move& m = moves[i];
    SCOPED_TRACE("move " + std::to_string(i) + " to/by " + std::to_string(m.value));
    ASSERT_TRUE(client_->write_i32(id, m.setpoint, m.value).ok());
    ASSERT_TRUE(client_->write_single(id, kCommand, m.command).ok());
    ASSERT_TRUE(wait_until([&] { return action_status(id) != 1; }, 30s))
        << "action stuck busy, x_position " << client_->read_input_i32(id, kXPosition).value_or(-1);
    ASSERT_EQ(action_status(id), 2)
        << "error " << client_->read_holding(id, kActionError, 1).values.at(0);
    EXPECT_EQ(client_->read_input_i32(id, kXPosition), m.expected_position);
  }
}

INSTANTIATE_TEST_SUITE_P(Bauds, CententRepeatedMoves, ::testing::Values("9600", "115200"));

// The same sequence while the units answer late now and then (a loaded machine): a move may
// fail (no reply, error), but no action may stay busy.
TEST_F(CententEndToEnd, RepeatedMovesWithLateRepliesNeverStayBusy) {
  start("0,1,2", {0, 1, 2}, ", poll: {fast: 200ms, slow: 2s}",
        {"--baud", "9600", "--emulate-wire", "--hop-delay-us", "500"}, "9600");
  wait_online({1, 2, 3});
  const int id = 2;
  std::mt19937 random(7);
  const int delays[] = {0, 0, 20, 40, 60, 90, 150};
  const int32_t targets[] = {3000, 0, 0, 3000, 3000, 0, 3000};
  for (int round = 0; round < 4; ++round)
    for (std::size_t i = 0; i < std::size(targets); ++i) {
      SCOPED_TRACE("round " + std::to_string(round) + " move " + std::to_string(i));
      plant_->sim().send_line("delay " + std::to_string(delays[random() % std::size(delays)]));
      if (!client_->write_i32(id, kXTarget, targets[i]).ok()) continue;
      if (!client_->write_single(id, kCommand, kMoveXAbsolute).ok()) continue;
      ASSERT_TRUE(wait_until([&] { return action_status(id) != 1; }, 30s))
          << "action stuck busy, x_position "
          << client_->read_input_i32(id, kXPosition).value_or(-1);
    }
  plant_->sim().send_line("delay 0");
}

}  // namespace
}  // namespace fieldgate::test
