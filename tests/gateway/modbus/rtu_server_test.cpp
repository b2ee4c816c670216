// ModbusRtuServer on a PTY: the io_context runs on the test thread, the "master" writes and
// reads the PTY's master side on its own thread.
#include "gateway/modbus/rtu_server.hpp"

#include <gtest/gtest.h>

#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <future>
#include <thread>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>

#include "gateway/modbus/rtu_codec.hpp"

namespace fieldgate::modbus {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;
using Clock = std::chrono::steady_clock;

class FakeHandler : public RequestHandler {
 public:
  static constexpr std::uint16_t slow_address = 50;  // writes take slow_delay

  explicit FakeHandler(asio::any_io_executor executor) : executor_(std::move(executor)) {
    for (std::uint16_t i = 0; i < holding.size(); ++i) holding[i] = static_cast<std::uint16_t>(i);
  }

  ReadBitsResult read_bits(std::uint8_t, BitTable, std::uint16_t, std::uint16_t) override {
    return ExceptionCode::illegal_function;
  }
  ReadRegistersResult read_registers(std::uint8_t unit, RegisterTable, std::uint16_t address,
                                     std::uint16_t count) override {
    if (address + count > holding.size()) return ExceptionCode::illegal_data_address;
    std::vector<std::uint16_t> out(holding.begin() + address, holding.begin() + address + count);
    out[0] = static_cast<std::uint16_t>(out[0] + 1000 * unit);
    return out;
  }
  asio::awaitable<WriteResult> write_registers(std::uint8_t unit, std::uint16_t address,
                                               std::span<const std::uint16_t> values) override {
    if (address + values.size() > holding.size()) co_return ExceptionCode::illegal_data_address;
    writes.push_back({unit, address, values[0]});
    if (address == slow_address) {
      asio::steady_timer timer(executor_, slow_delay);
      co_await timer.async_wait(asio::as_tuple(asio::use_awaitable));
    }
    holding[address] = values[0];
    co_return WriteResult::success();
  }
  asio::awaitable<WriteResult> write_coils(std::uint8_t, std::uint16_t,
                                           std::vector<bool>) override {
    co_return ExceptionCode::illegal_data_address;
  }

  struct Write {
    std::uint8_t unit;
    std::uint16_t address;
    std::uint16_t value;
    bool operator==(const Write&) const = default;
  };
  std::array<std::uint16_t, 200> holding{};
  std::vector<Write> writes;
  std::chrono::milliseconds slow_delay{500};

 private:
  asio::any_io_executor executor_;
};

Bytes adu(Bytes body) {
  Bytes out;
  encode_rtu_adu(body[0], std::span<const std::uint8_t>(body).subspan(1), out);
  return out;
}

class RtuServerTest : public ::testing::Test {
 protected:
  RtuServerTest() {
    if (::openpty(&master_, &slave_, name_, nullptr, nullptr) != 0) throw std::runtime_error("pty");
    termios tio{};
    ::tcgetattr(slave_, &tio);
    ::cfmakeraw(&tio);
    ::tcsetattr(slave_, TCSANOW, &tio);
    handler = std::make_shared<FakeHandler>(io.get_executor());
    options.serial.device = name_;
    options.serial.baud = 19200;
    options.units.set(1);
    options.units.set(2);
  }
  ~RtuServerTest() override {
    server.reset();
    io.run_for(20ms);
    ::close(master_);
    ::close(slave_);
  }

  void start() {
    server = std::make_unique<ModbusRtuServer>(io.get_executor(), options, handler);
    server->start();
    for (int i = 0; i < 100 && !server->stats().link_up; ++i) io.run_for(5ms);
  }

  // Runs the io_context while `client` runs on its own thread.
  // Runs the io_context while `client` runs on its own thread, and a little after, so frames
  // the client sent last are taken in even on a slow host.
  template <class F>
  auto with_master(F client) {
    auto result = std::async(std::launch::async, client);
    while (result.wait_for(0s) != std::future_status::ready) io.run_for(2ms);
    io.run_for(100ms);
    return result.get();
  }

  void send(const Bytes& b) { ASSERT_EQ(::write(master_, b.data(), b.size()), ssize_t(b.size())); }
  // What the server sends within `wait`, up to 30 ms of silence after its last byte.
  Bytes receive(std::chrono::milliseconds wait) {
    Bytes out;
    auto timeout = wait;
    for (;;) {
      pollfd p{master_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(timeout.count())) <= 0) return out;
      std::uint8_t buf[512];
      const auto n = ::read(master_, buf, sizeof buf);
      if (n <= 0) return out;
      out.insert(out.end(), buf, buf + n);
      timeout = 30ms;
    }
  }

  asio::io_context io;
  std::shared_ptr<FakeHandler> handler;
  ModbusRtuServerOptions options;
  std::unique_ptr<ModbusRtuServer> server;

 private:
  int master_ = -1, slave_ = -1;
  char name_[128]{};
};

TEST_F(RtuServerTest, AnswersAReadForItsUnit) {
  start();
  ASSERT_TRUE(server->stats().link_up) << server->last_error();
  const Bytes answer = with_master([&] {
    send(adu({0x02, 0x03, 0x00, 0x05, 0x00, 0x02}));
    return receive(1000ms);
  });
  EXPECT_EQ(answer, adu({0x02, 0x03, 0x04, 0x07, 0xD5, 0x00, 0x06}));  // 2005, 6
  EXPECT_EQ(server->stats().frames_ok, 1u);
  EXPECT_EQ(server->stats().functions[3].requests, 1u);
}

TEST_F(RtuServerTest, DropsBadCrcTruncatedAndOtherUnitsThenServesAgain) {
  start();
  const auto [bad, truncated, other, good] = with_master([&] {
    Bytes frame = adu({0x01, 0x03, 0x00, 0x00, 0x00, 0x01});
    frame[3] ^= 0x10;
    send(frame);
    Bytes r1 = receive(200ms);
    send(Bytes{0x01, 0x03, 0x00, 0x00, 0x00});
    Bytes r2 = receive(200ms);
    send(adu({0x05, 0x03, 0x00, 0x00, 0x00, 0x01}));
    Bytes r3 = receive(200ms);
    send(adu({0x01, 0x03, 0x00, 0x00, 0x00, 0x01}));
    Bytes r4 = receive(1000ms);
    return std::tuple{r1, r2, r3, r4};
  });
  EXPECT_TRUE(bad.empty());
  EXPECT_TRUE(truncated.empty());
  EXPECT_TRUE(other.empty());
  EXPECT_EQ(good, adu({0x01, 0x03, 0x02, 0x03, 0xE8}));
  const auto& s = server->stats();
  EXPECT_EQ(s.crc_errors, 1u);
  EXPECT_EQ(s.framing_errors, 1u);
  EXPECT_EQ(s.other_units, 1u);
  EXPECT_EQ(s.frames_ok, 1u);
}

TEST_F(RtuServerTest, ASilentGapSplitsAFrame) {
  start();
  const Bytes answer = with_master([&] {
    const Bytes frame = adu({0x01, 0x03, 0x00, 0x00, 0x00, 0x01});
    send(Bytes(frame.begin(), frame.begin() + 3));
    std::this_thread::sleep_for(50ms);  // t3.5 at 19200 baud is 2 ms
    send(Bytes(frame.begin() + 3, frame.end()));
    return receive(300ms);
  });
  EXPECT_TRUE(answer.empty());
  EXPECT_EQ(server->stats().crc_errors + server->stats().framing_errors, 2u);
}

TEST_F(RtuServerTest, BackToBackRequestsReadTogetherAreTakenApart) {
  start();
  const Bytes answer = with_master([&] {
    Bytes both = adu({0x01, 0x06, 0x00, 0x05, 0x00, 0x09});
    const Bytes read = adu({0x02, 0x03, 0x00, 0x00, 0x00, 0x01});
    both.insert(both.end(), read.begin(), read.end());
    send(both);
    return receive(1000ms);
  });
  // Only the latest is answered; the write still ran.
  EXPECT_EQ(answer, adu({0x02, 0x03, 0x02, 0x07, 0xD0}));
  EXPECT_EQ(handler->writes, (std::vector<FakeHandler::Write>{{1, 5, 9}}));
  EXPECT_EQ(server->stats().crc_errors, 0u);
}

TEST_F(RtuServerTest, AnIncompleteRequestWaitsForItsLastBytes) {
  // Far apart, so a loaded test host's late wake-up stays inside the window.
  options.incomplete_frame_wait = 500ms;
  start();
  const Bytes answer = with_master([&] {
    const Bytes frame = adu({0x01, 0x03, 0x00, 0x00, 0x00, 0x01});
    send(Bytes(frame.begin(), frame.begin() + 3));
    std::this_thread::sleep_for(30ms);  // well over t3.5 (2 ms), within the wait
    send(Bytes(frame.begin() + 3, frame.end()));
    return receive(1000ms);
  });
  EXPECT_EQ(answer, adu({0x01, 0x03, 0x02, 0x03, 0xE8}));
  EXPECT_EQ(server->stats().crc_errors + server->stats().framing_errors, 0u);
}

TEST_F(RtuServerTest, ASlowWriteDoesNotStallOtherUnitsAndItsLateAnswerIsDropped) {
  options.slow_writes = SlowWrites::silent;
  options.response_timeout = 2s;
  start();
  const auto [read_answer, late] = with_master([&] {
    send(adu({0x01, 0x06, 0x00, FakeHandler::slow_address, 0x00, 0x07}));
    std::this_thread::sleep_for(100ms);  // the master gave up on unit 1 and polls unit 2
    send(adu({0x02, 0x03, 0x00, 0x00, 0x00, 0x01}));
    Bytes r = receive(1000ms);
    return std::pair{r, receive(1000ms)};
  });
  EXPECT_EQ(read_answer, adu({0x02, 0x03, 0x02, 0x07, 0xD0}));
  EXPECT_TRUE(late.empty()) << "the write's answer came after the master moved on";
  EXPECT_EQ(handler->writes.size(), 1u);
  EXPECT_EQ(handler->holding[FakeHandler::slow_address], 7);
  EXPECT_EQ(server->stats().answers_dropped, 1u);
}

TEST_F(RtuServerTest, ASlowWriteIsAcknowledgedBeforeTheMasterTimesOut) {
  options.response_timeout = 300ms;
  handler->slow_delay = 700ms;
  start();
  const auto [first, later] = with_master([&] {
    send(adu({0x01, 0x06, 0x00, FakeHandler::slow_address, 0x00, 0x09}));
    Bytes r = receive(1000ms);
    return std::pair{r, receive(800ms)};
  });
  EXPECT_EQ(first, adu({0x01, 0x86, 0x05}));
  EXPECT_TRUE(later.empty());
  EXPECT_EQ(server->stats().acknowledged, 1u);
  EXPECT_EQ(server->stats().exceptions_by_code[5], 1u);
  EXPECT_EQ(handler->holding[FakeHandler::slow_address], 9);
}

TEST_F(RtuServerTest, ARetryJoinsTheRunningWriteInsteadOfRepeatingIt) {
  options.slow_writes = SlowWrites::silent;
  options.response_timeout = 400ms;
  handler->slow_delay = 600ms;
  start();
  const auto [first, retry] = with_master([&] {
    const Bytes write = adu({0x01, 0x06, 0x00, FakeHandler::slow_address, 0x00, 0x03});
    send(write);
    Bytes r = receive(400ms);  // the master's timeout: nothing
    send(write);
    return std::pair{r, receive(1000ms)};
  });
  EXPECT_TRUE(first.empty());
  EXPECT_EQ(retry, adu({0x01, 0x06, 0x00, FakeHandler::slow_address, 0x00, 0x03}));
  EXPECT_EQ(handler->writes.size(), 1u) << "the write ran twice";
  EXPECT_EQ(server->stats().retries_joined, 1u);
}

TEST_F(RtuServerTest, BroadcastOnlyTheConfiguredStopNeverAnswered) {
  options.broadcast.address = 100;
  options.broadcast.value = 0xFFFF;
  options.broadcast.writes = {{1, 6}, {2, 5}};
  start();
  const Bytes answers = with_master([&] {
    send(adu({0x00, 0x06, 0x00, 0x64, 0xFF, 0xFF}));
    Bytes r = receive(200ms);
    send(adu({0x00, 0x06, 0x00, 0x64, 0x00, 0x03}));  // another value: dropped
    const Bytes more = receive(200ms);
    r.insert(r.end(), more.begin(), more.end());
    send(adu({0x00, 0x03, 0x00, 0x00, 0x00, 0x01}));  // a broadcast read: dropped
    const Bytes last = receive(200ms);
    r.insert(r.end(), last.begin(), last.end());
    return r;
  });
  EXPECT_TRUE(answers.empty());
  EXPECT_EQ(handler->writes, (std::vector<FakeHandler::Write>{{1, 100, 6}, {2, 100, 5}}));
  EXPECT_EQ(server->stats().broadcasts_accepted, 1u);
  EXPECT_EQ(server->stats().broadcasts_dropped, 2u);
}

TEST_F(RtuServerTest, Rs485OnAPortWithoutItIsAClearError) {
  options.rs485.enabled = true;
  start();
  EXPECT_FALSE(server->stats().link_up);
  EXPECT_NE(server->last_error().find("TIOCSRS485"), std::string::npos) << server->last_error();
}

}  // namespace
}  // namespace fieldgate::modbus
