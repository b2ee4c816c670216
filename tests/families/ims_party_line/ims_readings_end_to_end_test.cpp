// The real daemon against fieldgate-sim-ims through Modbus TCP under each reading of the
// manual's reply layout (issue 20), and with replies slower than the reply timeout at 9600 baud
// with wire time and at 115200 (issue 12).
#include <gtest/gtest.h>

#include <chrono>
#include <random>
#include <regex>
#include <thread>

#include "harness.hpp"
#include "plant_test.hpp"

namespace fieldgate::test {
namespace {

using namespace std::chrono_literals;

// config/models/ims-indexer.yaml
constexpr int kPosition = 0;  // input registers 0-1
constexpr int kOutputs = 0;   // holding, write-only
constexpr int kCommand = 100, kActionStatus = 101;
constexpr int kTarget = 110;
constexpr int kMoveAbsolute = 1;

const char* kNodes =
    "      - {name: axis_a, address: A, model: ims-indexer, unit_id: 1}\n"
    "      - {name: axis_b, address: B, model: ims-indexer, unit_id: 2}\n"
    "      - {name: axis_c, address: C, model: ims-indexer, unit_id: 3}\n";

struct Reading {
  const char* name;
  std::vector<std::string> sim_args;
  const char* placement;  // what the daemon must log
};

std::ostream& operator<<(std::ostream& os, const Reading& r) {
  return os << r.name;
}

const Reading kReadings[] = {
    {"digest", {}, "next_line"},
    // gateway "A Z LF", unit "A Z space 0.00 CR LF"
    {"issue_example",
     {"--result-placement", "echo-line", "--result-padding", "space", "--decimals", "always",
      "--echo-linefeed", "at-execution", "--echo-name"},
     "echo_line"},
    {"next_line_bare",
     {"--result-padding", "none", "--result-end", "lf", "--decimals", "always", "--no-completion"},
     "next_line"},
    {"echo_line_bare_lf",
     {"--result-placement", "echo-line", "--result-padding", "none", "--result-end", "lf",
      "--decimals", "never"},
     "echo_line"},
};

std::unique_ptr<Plant> make_plant(const std::vector<std::string>& extra, const std::string& baud,
                                  bool wire, const std::string& timing) {
  std::vector<std::string> argv{FIELDGATE_SIM_IMS, "--link", "{link}", "--axes",
                                "A,B,C",           "--baud", baud};
  if (wire) argv.push_back("--emulate-wire");
  argv.insert(argv.end(), extra.begin(), extra.end());
  return std::make_unique<Plant>(std::vector<SimulatedBus>{
      SimulatedBus{"ims", "ims-party-line", argv, "baud: " + baud, timing, kNodes}});
}

class ImsReadingEndToEnd : public PlantFixture<::testing::TestWithParam<Reading>> {};

TEST_P(ImsReadingEndToEnd, ReadsMovesAndReadsBack) {
  plant_ = make_plant(GetParam().sim_args, "9600", true,
                      // Not a timing test: room for a loaded machine.
                      "reply_timeout: 200ms, byte_timeout: 50ms, retries: 2, offline_after: 5, "
                      "probe_interval: 500ms");
  client_ = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
  plant_->sim().send_line("position A 1000");
  plant_->sim().send_line("position C 123456");
  ASSERT_TRUE(wait_until(
      [&] {
        return client_->read_input_i32(1, kPosition) == 1000 &&
               client_->read_input_i32(2, kPosition) == 0 &&
               client_->read_input_i32(3, kPosition) == 123456;
      },
      20s))
      << "every node online with its position";
  ASSERT_TRUE(client_->write_i32(2, kTarget, 1500).ok());
  ASSERT_TRUE(client_->write_single(2, kCommand, kMoveAbsolute).ok());
  ASSERT_TRUE(wait_until([&] { return holding(2, kActionStatus) == 2; }, 60s));
  EXPECT_EQ(client_->read_input_i32(2, kPosition), 1500);
  EXPECT_EQ(client_->read_input_i32(1, kPosition), 1000);
  ASSERT_TRUE(wait_until(
      [&] {
        return plant_->daemon().log().find(std::string("unit B: result_placement detected: ") +
                                           GetParam().placement) != std::string::npos;
      },
      20s))
      << "the reading each unit uses is logged";
}

INSTANTIATE_TEST_SUITE_P(Readings, ImsReadingEndToEnd, ::testing::ValuesIn(kReadings),
                         [](const auto& info) { return std::string(info.param.name); });

// Replies slower than the reply timeout, changing every few hundred milliseconds: every value
// served as good is that axis' position, every write answered success ran on that axis.
struct LateCase {
  const char* name;
  const char* baud;
  bool wire;
  std::vector<std::string> sim_args;
};

std::ostream& operator<<(std::ostream& os, const LateCase& c) {
  return os << c.name;
}

class ImsLateEndToEnd : public PlantFixture<::testing::TestWithParam<LateCase>> {
 protected:
  // The sim's `status NAME` outputs field, after a control round trip.
  int sim_outputs(char name) {
    const auto answer = control_answer(plant_->sim(), std::string("status ") + name,
                                       std::string("ok ") + name + " position=");
    std::smatch m;
    if (!answer || !std::regex_search(*answer, m, std::regex(" outputs=([0-9]+)"))) return -1;
    return std::stoi(m[1]);
  }
};

TEST_P(ImsLateEndToEnd, NoWrongValueAndNoWrongConfirmation) {
  plant_ = make_plant(GetParam().sim_args, GetParam().baud, GetParam().wire,
                      "reply_timeout: 50ms, byte_timeout: 20ms, retries: 1, offline_after: 3, "
                      "probe_interval: 300ms");
  client_ = std::make_unique<ModbusClient>("127.0.0.1", plant_->port());
  const int32_t positions[] = {1000, -2500, 123456};
  plant_->sim().send_line("position A 1000");
  plant_->sim().send_line("position B -2500");
  plant_->sim().send_line("position C 123456");
  ASSERT_TRUE(wait_until([&] {
    for (int unit : {1, 2, 3})
      if (client_->read_input_i32(unit, kPosition) != positions[unit - 1]) return false;
    return true;
  }));
  std::mt19937 random(11);
  const int delays[] = {0, 10, 30, 45, 60, 80, 120};
  int good = 0, refused = 0, wrong = 0, writes_ok = 0, writes_wrong = 0;
  for (int round = 0; round < 12; ++round) {
    // The delay changes every few exchanges, so late replies of one request meet the next.
    const auto until = std::chrono::steady_clock::now() + 400ms;
    int delay = 0;
    while (std::chrono::steady_clock::now() < until) {
      delay = delays[random() % std::size(delays)];
      plant_->sim().send_line("delay " + std::to_string(delay));
      const int unit = 1 + static_cast<int>(random() % 3);
      const auto r = client_->read_input(unit, kPosition, 2);
      std::this_thread::sleep_for(std::chrono::milliseconds(random() % 4));
      if (!r.ok()) {
        ++refused;
        continue;
      }
      ++good;
      const auto value =
          static_cast<int32_t>((static_cast<uint32_t>(r.values[0]) << 16) | r.values[1]);
      if (value != positions[unit - 1]) {
        ++wrong;
        ADD_FAILURE() << "unit " << unit << " served " << value << " at delay " << delay;
      }
    }
    // A write of the outputs: success means that axis took it.
    const int unit = 1 + static_cast<int>(random() % 3);
    const int mask = 1 + static_cast<int>(random() % 7);
    if (client_->write_single(unit, kOutputs, 8 * mask).ok()) {
      ++writes_ok;
      const int seen = sim_outputs("ABC"[unit - 1]);
      if (seen != mask) {
        ++writes_wrong;
        ADD_FAILURE() << "write of " << mask << " to unit " << unit << " confirmed, axis has "
                      << seen;
      }
    }
  }
  plant_->sim().send_line("delay 0");
  std::cout << "[ measured ] " << GetParam().name << ": " << good << " good reads, " << wrong
            << " wrong; " << refused << " refused; " << writes_ok << " writes confirmed, "
            << writes_wrong << " wrong\n";
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(writes_wrong, 0);
  EXPECT_GT(good, 0);
  // Without the delay every axis answers again.
  ASSERT_TRUE(wait_until(
      [&] {
        for (int unit : {1, 2, 3}) {
          auto d = client_->read_input(unit, 1000, 1);
          if (!d.ok() || d.values[0] != 1) return false;
        }
        return true;
      },
      10s));
}

const LateCase kLateCases[] = {
    {"wire9600_digest", "9600", true, {}},
    {"wire9600_issue_example",
     "9600",
     true,
     {"--result-placement", "echo-line", "--result-padding", "space", "--decimals", "always",
      "--echo-linefeed", "at-execution", "--echo-name"}},
    {"baud115200_digest", "115200", false, {}},
    {"baud115200_echo_line",
     "115200",
     false,
     {"--result-placement", "echo-line", "--result-padding", "none", "--result-end", "lf"}},
};

INSTANTIATE_TEST_SUITE_P(Cases, ImsLateEndToEnd, ::testing::ValuesIn(kLateCases),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fieldgate::test
