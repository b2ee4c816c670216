#include "fault_property.hpp"

#include <algorithm>
#include <thread>
#include <utility>

namespace fieldgate::test {

using namespace std::chrono_literals;

SimulatedBus fault_bus(std::string name, std::string protocol, std::vector<std::string> sim_argv,
                       const FaultRun& run, const std::string& byte_timeout) {
  SimulatedBus bus;
  bus.name = std::move(name);
  bus.protocol = std::move(protocol);
  bus.sim_argv = std::move(sim_argv);
  if (run.slow_wire) {
    for (const char* a : {"--baud", "9600", "--emulate-wire"}) bus.sim_argv.push_back(a);
    bus.serial = "baud: 9600";
  }
  bus.timing =
      // A line this bad would take nodes offline every few polls with offline_after: 3 (it
      // counts attempts); the property is about the exchanges, so keep them online.
      "reply_timeout: 100ms, byte_timeout: " + byte_timeout +
      ", retries: 1, offline_after: 10, probe_interval: 300ms";
  return bus;
}

void check_ends_in_unit(ModbusClient& reader, int unit, int address, const std::string& what,
                        FaultReads& reads) {
  auto r = reader.read_holding(unit, address, 2);
  if (!r.ok()) return;
  const int32_t value = i32_at(r, 0);
  if (value != 0 && value % 10 != unit) reads.wrong_value(unit, what, value);
}

std::vector<JournalEntry>::const_iterator find_request(const std::vector<JournalEntry>& journal,
                                                       const std::string& request) {
  return std::find_if(journal.begin(), journal.end(),
                      [&](const JournalEntry& e) { return e.request == request; });
}

std::function<FaultWrite(ModbusClient&, int, int, std::mt19937&)> write_unique_values(int address) {
  return [address](ModbusClient& client, int i, int unit, std::mt19937&) {
    const int value = 1000 + i * 10 + unit;
    return FaultWrite{.value = value,
                      .exception = client.write_single(unit, address, value).exception};
  };
}

namespace {

int draw_unit(const FaultProperty& property, std::mt19937& random) {
  return property.units == 1 ? 1 : 1 + static_cast<int>(random() % property.units);
}

// Reads the units from a second connection until running is cleared.
void read_units(const Plant& plant, unsigned seed, const FaultProperty& property,
                const std::atomic<bool>& running, FaultReads& reads) {
  auto second = std::make_unique<ModbusClient>("127.0.0.1", plant.port());
  std::mt19937 random(seed + 1000);
  while (running) {
    const int unit = draw_unit(property, random);
    auto r = second->read_input(unit, property.inputs.address, property.inputs.count);
    // A connection that missed an answer would take it for the next one's: start afresh.
    if (property.fresh_connection_on_no_answer && !answered(r.exception))
      second = std::make_unique<ModbusClient>("127.0.0.1", plant.port());
    if (r.ok()) ++reads.good;
    property.check_read(*second, unit, r, reads);
    // A value served wrong stays in the image until the next poll, tens of milliseconds, so a
    // read every 2 ms still sees it. Unpaced, this loop and the daemon answering it took half a
    // core each, and several such tests at once ran for minutes or past their ctest timeout.
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

}  // namespace

void run_fault_property(Plant& plant, std::unique_ptr<ModbusClient>& client, unsigned seed,
                        const FaultProperty& property) {
  // Late replies start 150 ms after the request, well past the 100 ms reply timeout (and inside
  // the default guard window and the late-reply window of 5 reply timeouts).
  plant.sim().send_line("chaos " + std::to_string(seed) + " 25 5 5 5 150");

  std::atomic<bool> running{true};
  FaultReads reads;
  std::thread reader([&] { read_units(plant, seed, property, running, reads); });

  // Each write is unique, so the journal tells whose reply confirmed what.
  std::vector<FaultWrite> writes;
  std::mt19937 random(seed);
  // At least 24 writes, and more until a few went through (how many do depends on the load of
  // the test machine as much as on the faults: a failed proof answers 0x0B without sending).
  int confirmed = 0;
  for (int i = 1; i <= 24 || (confirmed < 4 && i <= 96); ++i) {
    const int unit = draw_unit(property, random);
    // A unit taken offline by the faults is only probed now and then: wait for it, so that
    // writes reach devices rather than being refused at the gateway.
    wait_until(
        [&] {
          return client->read_input(unit, property.online.address, property.online.count).ok();
        },
        3s);
    const auto started = std::chrono::steady_clock::now();
    FaultWrite w = property.write(*client, i, unit, random);
    w.unit = unit;
    w.took = std::chrono::duration_cast<std::chrono::milliseconds>(
        std::chrono::steady_clock::now() - started);
    // No answer is no confirmation; a fresh connection, so that the late answer is not
    // taken for the next write's.
    if (property.fresh_connection_on_no_answer && !answered(w.exception)) {
      w.exception = kNoAnswer;
      client = std::make_unique<ModbusClient>("127.0.0.1", plant.port());
    }
    if (w.exception == 0 && !w.refused) ++confirmed;
    writes.push_back(w);
    std::this_thread::sleep_for(std::chrono::milliseconds(random() % 40));
  }
  plant.sim().send_line("chaos off");
  running = false;
  reader.join();

  EXPECT_EQ(reads.wrong.load(), 0) << reads.first_wrong;
  EXPECT_GT(reads.good.load(), 10);

  const auto journal = read_journal(plant.dir() / "journal");
  int successes = 0, unknown = 0;
  for (const auto& w : writes) {
    EXPECT_TRUE(expected_write_outcome(w.exception) &&
                (property.fresh_connection_on_no_answer || w.exception != kNoAnswer))
        << "exception " << w.exception << " after " << w.took.count() << " ms";
    if (w.exception == kTargetFailed) ++unknown;
    if (w.refused) {
      EXPECT_NE(w.exception, 0) << property.refused_confirmed;
      continue;
    }
    if (w.exception != 0) continue;
    ++successes;
    property.check_confirmed(w, journal);
    if (::testing::Test::HasFatalFailure()) return;
  }
  expect_faults_and_confirmed_writes(successes, unknown, writes.size(), journal);
}

}  // namespace fieldgate::test
