// ModbusTcpServer on loopback: the io_context runs on the test thread, clients (libmodbus, or
// raw sockets for misbehaviour) run on their own threads because they block.
#include "gateway/modbus/tcp_server.hpp"

#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <functional>
#include <future>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/use_awaitable.hpp>

#include "gateway/modbus/mbap.hpp"

namespace fieldgate::modbus {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;
using Clock = std::chrono::steady_clock;

// A register map of `size` items per table. Special addresses misbehave on purpose, like
// libmodbus's UT_REGISTERS_ADDRESS_* in its unit-test server.
class FakeHandler : public RequestHandler {
 public:
  static constexpr std::uint16_t size = 1000;
  static constexpr std::uint16_t slow_address = 800;    // writes wait for release_slow_writes()
  static constexpr std::uint16_t failed_address = 900;  // the "controller" does not answer: 0x0B
  static constexpr std::uint16_t error_address = 901;   // the "controller" reports an error: 0x04

  FakeHandler(asio::any_io_executor executor, std::uint16_t base)
      : holding(size), input(size), coils(size), discrete(size), release_(executor) {
    for (std::uint16_t i = 0; i < size; ++i) {
      holding[i] = static_cast<std::uint16_t>(base + i);
      input[i] = static_cast<std::uint16_t>(0x1000 + i);
      coils[i] = i % 2 == 1;
      discrete[i] = i % 3 == 0;
    }
    release_.expires_at(Clock::time_point::max());
  }

  ReadBitsResult read_bits(std::uint8_t unit, BitTable table, std::uint16_t address,
                           std::uint16_t count) override {
    last_unit = unit;
    if (auto e = check(address, count)) return *e;
    const auto& bits = table == BitTable::coils ? coils : discrete;
    return std::vector<bool>(bits.begin() + address, bits.begin() + address + count);
  }

  ReadRegistersResult read_registers(std::uint8_t unit, RegisterTable table, std::uint16_t address,
                                     std::uint16_t count) override {
    last_unit = unit;
    if (auto e = check(address, count)) return *e;
    const auto& registers = table == RegisterTable::holding_registers ? holding : input;
    return std::vector<std::uint16_t>(registers.begin() + address,
                                      registers.begin() + address + count);
  }

  asio::awaitable<WriteResult> write_registers(std::uint8_t unit, std::uint16_t address,
                                               std::span<const std::uint16_t> values) override {
    last_unit = unit;
    const auto count = static_cast<std::uint16_t>(values.size());
    if (auto e = check(address, count)) co_return *e;
    if (covers(address, count, slow_address)) co_await wait_for_release();
    std::copy(values.begin(), values.end(), holding.begin() + address);
    co_return WriteResult::success();
  }

  asio::awaitable<WriteResult> write_coils(std::uint8_t unit, std::uint16_t address,
                                           std::vector<bool> values) override {
    last_unit = unit;
    const auto count = static_cast<std::uint16_t>(values.size());
    if (auto e = check(address, count)) co_return *e;
    if (covers(address, count, slow_address)) co_await wait_for_release();
    std::copy(values.begin(), values.end(), coils.begin() + address);
    co_return WriteResult::success();
  }

  void release_slow_writes() { release_.cancel(); }

  std::vector<std::uint16_t> holding, input;
  std::vector<bool> coils, discrete;
  std::atomic<int> last_unit{-1};
  std::atomic<int> slow_writes_pending{0};

 private:
  static bool covers(std::uint16_t address, std::uint16_t count, std::uint16_t item) {
    return address <= item && item < address + count;
  }

  static std::optional<ExceptionCode> check(std::uint16_t address, std::uint16_t count) {
    if (address + count > size) return ExceptionCode::illegal_data_address;
    if (covers(address, count, failed_address)) return ExceptionCode::gateway_target_failed;
    if (covers(address, count, error_address)) return ExceptionCode::server_device_failure;
    return std::nullopt;
  }

  asio::awaitable<void> wait_for_release() {
    ++slow_writes_pending;
    co_await release_.async_wait(asio::as_tuple(asio::use_awaitable));
    --slow_writes_pending;
  }

  asio::steady_timer release_;
};

// libmodbus TCP client; blocking, so only used on client threads.
class Client {
 public:
  Client(std::uint16_t port, int unit = 1, const char* host = "127.0.0.1")
      : ctx_(std::string_view(host).find(':') == std::string_view::npos
                 ? modbus_new_tcp(host, port)
                 : modbus_new_tcp_pi(host, std::to_string(port).c_str())) {
    modbus_set_slave(ctx_, unit);
    modbus_set_response_timeout(ctx_, 3, 0);
  }
  ~Client() {
    modbus_close(ctx_);
    modbus_free(ctx_);
  }
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  bool connect() { return modbus_connect(ctx_) == 0; }
  void set_response_timeout(std::chrono::seconds timeout) {
    modbus_set_response_timeout(ctx_, static_cast<std::uint32_t>(timeout.count()), 0);
  }
  modbus_t* get() { return ctx_; }

  // Reads one holding register; -1 on any error.
  int read_one(int address) {
    std::uint16_t value = 0;
    return modbus_read_registers(ctx_, address, 1, &value) == 1 ? value : -1;
  }

 private:
  modbus_t* ctx_;
};

// A plain socket for sending what libmodbus never would: half requests, bad headers, pipelines.
class RawClient {
 public:
  // `source`: a loopback address to connect from (127.0.0.2, ...), for per-address limits.
  explicit RawClient(std::uint16_t port, const char* source = nullptr)
      : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    if (source) {
      sockaddr_in from{};
      from.sin_family = AF_INET;
      ::inet_pton(AF_INET, source, &from.sin_addr);
      ::bind(fd_, reinterpret_cast<sockaddr*>(&from), sizeof from);
    }
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  }
  ~RawClient() { ::close(fd_); }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;

  bool connected() const { return connected_; }

  bool send(const Bytes& bytes) {
    return ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) ==
           static_cast<ssize_t>(bytes.size());
  }

  // Up to n bytes; fewer on timeout, end of stream or error (then closed() is true).
  Bytes receive(std::size_t n, std::chrono::milliseconds timeout = 3000ms) {
    Bytes out;
    const auto deadline = Clock::now() + timeout;
    while (out.size() < n && !closed_) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      pollfd p{fd_, POLLIN, 0};
      if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) break;
      std::uint8_t buffer[512];
      const ssize_t r = ::recv(fd_, buffer, std::min(n - out.size(), sizeof buffer), 0);
      if (r <= 0) {
        closed_ = true;
        break;
      }
      out.insert(out.end(), buffer, buffer + r);
    }
    return out;
  }

  // Waits until the server closes the connection; anything received meanwhile is returned
  // through `received`. False on timeout.
  bool wait_closed(std::chrono::milliseconds timeout, Bytes* received = nullptr) {
    Bytes data = receive(100000, timeout);
    if (received) *received = std::move(data);
    return closed_;
  }

  bool closed() const { return closed_; }

 private:
  int fd_;
  bool connected_ = false;
  bool closed_ = false;
};

Bytes adu(std::uint16_t transaction_id, std::uint8_t unit, const Bytes& pdu) {
  Bytes out;
  encode_adu(transaction_id, unit, pdu, out);
  return out;
}

Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const Bytes& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

bool wait_until(const std::function<bool()>& condition, std::chrono::milliseconds timeout = 5s) {
  const auto deadline = Clock::now() + timeout;
  while (!condition()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

class ModbusTcpServerTest : public ::testing::Test {
 protected:
  ModbusTcpServerOptions loopback_options() {
    ModbusTcpServerOptions options;
    options.endpoint = {asio::ip::make_address("127.0.0.1"), 0};
    options.idle_timeout = 10s;
    options.request_timeout = 5s;
    return options;
  }

  void start_server(ModbusTcpServerOptions options) {
    options_ = options;
    server_ = std::make_unique<ModbusTcpServer>(io_.get_executor(), std::move(options), handler_);
    server_->start();
    port_ = server_->local_endpoint().port();
    ASSERT_NE(port_, 0);
  }
  void start_server() { start_server(loopback_options()); }

  // Runs each client on its own thread while this thread runs the io_context, until every
  // client has returned.
  void run_clients(std::vector<std::function<void()>> clients) {
    std::atomic<std::size_t> done{0};
    std::vector<std::thread> threads;
    for (auto& client : clients) {
      threads.emplace_back([&done, client] {
        client();
        ++done;
      });
    }
    const auto limit = Clock::now() + 30s;
    while (done < clients.size() && Clock::now() < limit) {
      io_.run_one_for(10ms);
      if (io_.stopped()) {  // out of work, e.g. after stop(): keep polling for the clients
        io_.restart();
        std::this_thread::sleep_for(1ms);
      }
    }
    EXPECT_EQ(done, clients.size()) << "a client hung";
    for (auto& t : threads) t.join();
  }
  void run_client(std::function<void()> client) { run_clients({std::move(client)}); }

  // From a client thread: runs f on the io_context's thread and returns its result.
  template <class F>
  auto on_io(F f) -> decltype(f()) {
    std::packaged_task<decltype(f())()> task(std::move(f));
    auto result = task.get_future();
    asio::post(io_, [&task] { task(); });
    return result.get();
  }

  std::uint64_t connected_clients() {
    return on_io([this] { return server_->stats().clients_connected; });
  }

  asio::io_context io_;
  std::shared_ptr<FakeHandler> handler_ = std::make_shared<FakeHandler>(io_.get_executor(), 0);
  std::unique_ptr<ModbusTcpServer> server_;
  ModbusTcpServerOptions options_;
  std::uint16_t port_ = 0;
};

TEST_F(ModbusTcpServerTest, ReadsAllFourTables) {
  start_server();
  run_client([&] {
    Client c(port_);
    ASSERT_TRUE(c.connect());
    std::uint16_t registers[125];
    ASSERT_EQ(modbus_read_registers(c.get(), 10, 5, registers), 5);
    for (int i = 0; i < 5; ++i) EXPECT_EQ(registers[i], 10 + i);
    ASSERT_EQ(modbus_read_input_registers(c.get(), 0, 125, registers), 125);
    for (int i = 0; i < 125; ++i) EXPECT_EQ(registers[i], 0x1000 + i);
    std::uint8_t bits[2000];
    ASSERT_EQ(modbus_read_bits(c.get(), 3, 20, bits), 20);
    for (int i = 0; i < 20; ++i) EXPECT_EQ(bits[i], (3 + i) % 2 == 1) << i;
    ASSERT_EQ(modbus_read_input_bits(c.get(), 0, 899, bits), 899) << modbus_strerror(errno);
    for (int i = 0; i < 899; ++i) EXPECT_EQ(bits[i], i % 3 == 0) << i;
  });
}

TEST_F(ModbusTcpServerTest, WritesReachTheHandler) {
  start_server();
  run_client([&] {
    Client c(port_);
    ASSERT_TRUE(c.connect());
    EXPECT_EQ(modbus_write_register(c.get(), 5, 0xABCD), 1);
    std::uint16_t values[123];
    for (int i = 0; i < 123; ++i) values[i] = static_cast<std::uint16_t>(0x4000 + i);
    EXPECT_EQ(modbus_write_registers(c.get(), 100, 123, values), 123);
    EXPECT_EQ(modbus_write_bit(c.get(), 8, TRUE), 1);
    std::uint8_t bits[20];
    for (int i = 0; i < 20; ++i) bits[i] = i % 4 == 0;
    EXPECT_EQ(modbus_write_bits(c.get(), 200, 20, bits), 20);
    const std::uint16_t source[3] = {0x0A0A, 0x0B0B, 0x0C0C};
    std::uint16_t read_back[5];
    ASSERT_EQ(modbus_write_and_read_registers(c.get(), 300, 3, source, 299, 5, read_back), 5);
    EXPECT_EQ(read_back[0], 299);
    EXPECT_EQ(read_back[1], 0x0A0A);
    EXPECT_EQ(read_back[3], 0x0C0C);
    EXPECT_EQ(read_back[4], 303);
  });
  EXPECT_EQ(handler_->holding[5], 0xABCD);
  EXPECT_EQ(handler_->holding[100], 0x4000);
  EXPECT_EQ(handler_->holding[222], 0x4000 + 122);
  EXPECT_EQ(handler_->holding[223], 223);
  EXPECT_TRUE(handler_->coils[8]);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(handler_->coils[200 + i], i % 4 == 0) << i;
}

TEST_F(ModbusTcpServerTest, ExceptionCodesArriveAtTheClient) {
  start_server();
  run_client([&] {
    Client c(port_);
    ASSERT_TRUE(c.connect());
    std::uint16_t registers[10];
    std::uint8_t bits[10] = {};
    EXPECT_EQ(modbus_read_registers(c.get(), FakeHandler::failed_address, 1, registers), -1);
    EXPECT_EQ(errno, EMBXGTAR);
    EXPECT_EQ(modbus_read_input_registers(c.get(), 895, 10, registers), -1);
    EXPECT_EQ(errno, EMBXGTAR);
    EXPECT_EQ(modbus_read_registers(c.get(), FakeHandler::error_address, 1, registers), -1);
    EXPECT_EQ(errno, EMBXSFAIL);
    EXPECT_EQ(modbus_read_registers(c.get(), 995, 10, registers), -1);
    EXPECT_EQ(errno, EMBXILADD);
    EXPECT_EQ(modbus_read_bits(c.get(), 999, 2, bits), -1);
    EXPECT_EQ(errno, EMBXILADD);
    EXPECT_EQ(modbus_write_register(c.get(), FakeHandler::failed_address, 1), -1);
    EXPECT_EQ(errno, EMBXGTAR);
    EXPECT_EQ(modbus_write_bits(c.get(), FakeHandler::error_address, 3, bits), -1);
    EXPECT_EQ(errno, EMBXSFAIL);

    // Requests libmodbus would refuse to build, checked by the server itself.
    const auto raw = [&](Bytes request) {
      EXPECT_GT(modbus_send_raw_request(c.get(), request.data(), static_cast<int>(request.size())),
                0);
      std::uint8_t response[MODBUS_TCP_MAX_ADU_LENGTH];
      const int n = modbus_receive_confirmation(c.get(), response);
      return n < 0 ? Bytes{} : Bytes(response + 7, response + n);
    };
    EXPECT_EQ(raw({1, 0x03, 0x00, 0x00, 0x00, 0x7E}), (Bytes{0x83, 0x03}));  // 126 registers
    EXPECT_EQ(raw({1, 0x08, 0x00, 0x00, 0x12, 0x34}), (Bytes{0x88, 0x01}));  // diagnostics
    EXPECT_EQ(raw({1, 0x05, 0x00, 0x01, 0x12, 0x34}), (Bytes{0x85, 0x03}));  // coil value
    EXPECT_EQ(raw({1, 0x04, 0xFF, 0xFF, 0x00, 0x02}), (Bytes{0x84, 0x02}));  // past 0xFFFF

    // The connection survives exceptions.
    EXPECT_EQ(c.read_one(7), 7);
  });
}

TEST_F(ModbusTcpServerTest, UnitIdIsPassedThroughAndEchoed) {
  start_server();
  run_client([&] {
    Client c(port_, 17);
    ASSERT_TRUE(c.connect());
    EXPECT_EQ(c.read_one(1), 1);
    EXPECT_EQ(handler_->last_unit, 17);

    RawClient raw(port_);
    ASSERT_TRUE(raw.connected());
    for (int unit : {0, 255}) {
      const auto u = static_cast<std::uint8_t>(unit);
      ASSERT_TRUE(raw.send(adu(0x1234, u, {0x03, 0x00, 0x02, 0x00, 0x01})));
      EXPECT_EQ(raw.receive(11),
                (Bytes{0x12, 0x34, 0x00, 0x00, 0x00, 0x05, u, 0x03, 0x02, 0x00, 0x02}));
      EXPECT_EQ(handler_->last_unit, unit);
    }
  });
}

TEST_F(ModbusTcpServerTest, SlowWriteDoesNotStallOtherClients) {
  start_server();
  Clock::time_point write_returned, reads_done;
  run_clients({
      [&] {
        Client writer(port_);
        writer.set_response_timeout(20s);
        ASSERT_TRUE(writer.connect());
        EXPECT_EQ(modbus_write_register(writer.get(), FakeHandler::slow_address, 42), 1);
        write_returned = Clock::now();
      },
      [&] {
        Client reader(port_);
        ASSERT_TRUE(reader.connect());
        const bool pending = wait_until([&] { return handler_->slow_writes_pending == 1; });
        EXPECT_TRUE(pending);
        // libmodbus's 3 s response timeout would fail these if the server waited on the write.
        for (int i = 0; pending && i < 50; ++i) EXPECT_EQ(reader.read_one(i), i);
        reads_done = Clock::now();
        EXPECT_EQ(handler_->slow_writes_pending, 1);
        asio::post(io_, [&] { handler_->release_slow_writes(); });
      },
  });
  EXPECT_LT(reads_done, write_returned);
  EXPECT_EQ(handler_->holding[FakeHandler::slow_address], 42);
}

TEST_F(ModbusTcpServerTest, PipelinedRequestsAreAnsweredInOrder) {
  start_server();
  run_client([&] {
    RawClient raw(port_);
    ASSERT_TRUE(raw.connected());
    const std::uint8_t hi = FakeHandler::slow_address >> 8, lo = FakeHandler::slow_address & 0xFF;
    ASSERT_TRUE(raw.send(
        cat({adu(1, 1, {0x03, 0x00, 0x07, 0x00, 0x01}), adu(2, 1, {0x06, hi, lo, 0x00, 0x63}),
             adu(3, 1, {0x03, hi, lo, 0x00, 0x01})})));
    EXPECT_EQ(raw.receive(11), (Bytes{0, 1, 0, 0, 0, 5, 1, 0x03, 0x02, 0x00, 0x07}));
    ASSERT_TRUE(wait_until([&] { return handler_->slow_writes_pending == 1; }));
    // The read queued behind the write is not answered before it.
    EXPECT_TRUE(raw.receive(1, 200ms).empty());
    asio::post(io_, [&] { handler_->release_slow_writes(); });
    EXPECT_EQ(raw.receive(12), (Bytes{0, 2, 0, 0, 0, 6, 1, 0x06, hi, lo, 0x00, 0x63}));
    EXPECT_EQ(raw.receive(11), (Bytes{0, 3, 0, 0, 0, 5, 1, 0x03, 0x02, 0x00, 0x63}));
  });
}

TEST_F(ModbusTcpServerTest, HalfRequestDoesNotBlockOthersAndTimesOut) {
  auto options = loopback_options();
  options.request_timeout = 300ms;
  start_server(options);
  run_client([&] {
    RawClient stalled(port_);
    ASSERT_TRUE(stalled.connected());
    // Taken before sending: the server's deadline may start before this thread runs again.
    const auto sent = Clock::now();
    ASSERT_TRUE(stalled.send({0x00, 0x01, 0x00, 0x00, 0x00}));  // 5 of the 7 header bytes
    Client other(port_);
    ASSERT_TRUE(other.connect());
    for (int i = 0; i < 20; ++i) EXPECT_EQ(other.read_one(i), i);
    Bytes received;
    EXPECT_TRUE(stalled.wait_closed(3s, &received));
    EXPECT_TRUE(received.empty());
    EXPECT_GE(Clock::now() - sent, 300ms);
    EXPECT_EQ(other.read_one(3), 3);
  });
  EXPECT_EQ(server_->stats().clients_timed_out, 1u);
}

TEST_F(ModbusTcpServerTest, DripFedRequestIsDroppedByTheRequestTimeout) {
  // One byte per 100 ms keeps the connection busy but never completes a request in 300 ms.
  auto options = loopback_options();
  options.request_timeout = 300ms;
  start_server(options);
  run_client([&] {
    RawClient slow(port_);
    ASSERT_TRUE(slow.connected());
    const Bytes request = adu(1, 1, {0x03, 0x00, 0x00, 0x00, 0x01});
    std::size_t sent = 0;
    while (sent < request.size() && slow.send({request[sent]})) {
      ++sent;
      if (!slow.receive(1, 100ms).empty() || slow.closed()) break;
    }
    EXPECT_TRUE(slow.closed());
    EXPECT_LT(sent, request.size());
  });
  EXPECT_EQ(server_->stats().clients_timed_out, 1u);
}

TEST_F(ModbusTcpServerTest, IdleClientIsDroppedWhileActiveClientStays) {
  auto options = loopback_options();
  options.idle_timeout = 300ms;
  start_server(options);
  run_client([&] {
    // Taken before connecting: the server may accept before this thread runs again.
    const auto connected = Clock::now();
    RawClient idle(port_);
    ASSERT_TRUE(idle.connected());
    Client active(port_);
    ASSERT_TRUE(active.connect());
    for (int i = 0; i < 8; ++i) {  // 800 ms of requests 100 ms apart
      std::this_thread::sleep_for(100ms);
      EXPECT_EQ(active.read_one(i), i);
    }
    EXPECT_TRUE(idle.wait_closed(2s));
    EXPECT_GE(Clock::now() - connected, 300ms);
    EXPECT_EQ(connected_clients(), 1u);
  });
  EXPECT_EQ(server_->stats().clients_timed_out, 1u);
}

TEST_F(ModbusTcpServerTest, IdleTimeoutAppliesAgainAfterAWrite) {
  // While a write is confirmed there is no deadline; afterwards the idle one must come back.
  auto options = loopback_options();
  options.idle_timeout = 300ms;
  start_server(options);
  run_client([&] {
    RawClient raw(port_);
    ASSERT_TRUE(raw.connected());
    ASSERT_TRUE(raw.send(adu(1, 1, {0x06, 0x00, 0x05, 0x12, 0x34})));
    EXPECT_EQ(raw.receive(12), (Bytes{0, 1, 0, 0, 0, 6, 1, 0x06, 0x00, 0x05, 0x12, 0x34}));
    const auto answered = Clock::now();
    EXPECT_TRUE(raw.wait_closed(2s));
    EXPECT_GE(Clock::now() - answered, 250ms);
  });
  EXPECT_EQ(server_->stats().clients_timed_out, 1u);
  EXPECT_EQ(handler_->holding[5], 0x1234);
}

TEST_F(ModbusTcpServerTest, MaxClientsRefusesExtraConnections) {
  auto options = loopback_options();
  options.max_clients = 2;
  options.when_full = WhenFull::refuse;
  start_server(options);
  run_client([&] {
    auto first = std::make_unique<Client>(port_);
    Client second(port_);
    ASSERT_TRUE(first->connect());
    ASSERT_TRUE(second.connect());
    EXPECT_EQ(first->read_one(1), 1);
    EXPECT_EQ(second.read_one(2), 2);

    Client third(port_);
    third.connect();  // the kernel completes the handshake; the server then closes it
    EXPECT_EQ(third.read_one(3), -1);

    first.reset();
    ASSERT_TRUE(wait_until([&] { return connected_clients() == 1; }));
    Client fourth(port_);
    ASSERT_TRUE(fourth.connect());
    EXPECT_EQ(fourth.read_one(4), 4);
    EXPECT_EQ(second.read_one(5), 5);
  });
  EXPECT_EQ(server_->stats().clients_refused, 1u);
  EXPECT_EQ(server_->stats().clients_accepted, 3u);
}

TEST_F(ModbusTcpServerTest, WhenFullTheIdlestIsEvictedButNeverOneBeingAnswered) {
  auto options = loopback_options();
  options.max_clients = 2;  // when_full: evict_idle is the default
  start_server(options);
  run_client([&] {
    // The oldest request, but its write is still being confirmed.
    RawClient slow(port_);
    ASSERT_TRUE(slow.send(adu(1, 1, {0x06, 0x03, 0x20, 0x00, 0x07})));  // holding 800
    ASSERT_TRUE(wait_until([&] { return handler_->slow_writes_pending == 1; }));
    RawClient idle(port_);  // connected later, sends nothing
    ASSERT_TRUE(wait_until([&] { return connected_clients() == 2; }));

    Client plc(port_);
    ASSERT_TRUE(plc.connect());
    EXPECT_EQ(plc.read_one(5), 5);
    EXPECT_TRUE(idle.wait_closed(2s));

    on_io([&] {
      handler_->release_slow_writes();
      return 0;
    });
    EXPECT_EQ(slow.receive(12), adu(1, 1, {0x06, 0x03, 0x20, 0x00, 0x07}));
  });
  EXPECT_EQ(server_->stats().clients_evicted, 1u);
  EXPECT_EQ(server_->stats().clients_refused, 0u);
}

// Peers that connect and say nothing, from 8 addresses, keep every slot changing hands while a
// client polls on one connection: it is never the one evicted (it has been answered; they have
// not completed a request), so it keeps every read. Counts, no timing.
TEST_F(ModbusTcpServerTest, SilentChurnNeverEvictsAPollingClient) {
  auto options = loopback_options();
  options.max_clients = 4;  // when_full: evict_idle; no connect rate limit
  start_server(options);
  std::atomic<bool> polling{true};
  std::atomic<int> reads{0}, failed{0};
  std::atomic<int> churned{0};
  constexpr int wanted = 300;
  auto churn = [&](int first) {
    return [&, first] {
      const std::string sources[] = {"127.0.0." + std::to_string(first),
                                     "127.0.0." + std::to_string(first + 1)};
      std::vector<std::unique_ptr<RawClient>> open;
      for (int i = 0; polling; ++i) {
        open.push_back(std::make_unique<RawClient>(port_, sources[i % 2].c_str()));
        ++churned;
        if (open.size() > 10) open.erase(open.begin());  // keeps at most 10 open
      }
    };
  };
  auto poller = [&] {
    Client plc(port_);
    ASSERT_TRUE(plc.connect());
    // Until the churn has gone round the slots many times over, and at least `wanted` reads.
    while (reads + failed < wanted || churned < 2000) {
      (plc.read_one(7) == 7 ? reads : failed)++;
      std::this_thread::sleep_for(1ms);
    }
    polling = false;
  };
  run_clients({poller, churn(2), churn(4), churn(6), churn(8)});
  EXPECT_EQ(failed, 0) << "of " << reads + failed << " reads";
  EXPECT_GE(reads, wanted);
  const auto& stats = server_->stats();
  EXPECT_GT(stats.evicted.never_spoke, 0u);
  EXPECT_EQ(stats.evicted.overdue, 0u);
  EXPECT_EQ(stats.clients_evicted, stats.evicted.never_spoke);
}

// Full of clients that have been answered and still poll: a newcomer is let in on probation
// and, at its first request, closed unanswered; nobody working is pushed out for it.
TEST_F(ModbusTcpServerTest, FullOfWorkingClientsANewcomerIsRefusedAtItsFirstRequest) {
  auto options = loopback_options();
  options.max_clients = 2;
  start_server(options);
  run_client([&] {
    Client a(port_), b(port_);
    ASSERT_TRUE(a.connect());
    ASSERT_TRUE(b.connect());
    EXPECT_EQ(a.read_one(1), 1);
    EXPECT_EQ(b.read_one(2), 2);
    Client c(port_);
    c.connect();
    EXPECT_EQ(c.read_one(3), -1);
    EXPECT_EQ(a.read_one(4), 4);
    EXPECT_EQ(b.read_one(5), 5);
  });
  EXPECT_EQ(server_->stats().refused.no_idle_client, 1u);
  EXPECT_EQ(server_->stats().clients_evicted, 0u);
}

// A client gone silent well beyond its own rhythm (a PLC whose old connection is half-open
// after a restart) makes room for the newcomer once the newcomer has spoken.
TEST_F(ModbusTcpServerTest, AnOverdueClientMakesRoomForANewcomerThatSpoke) {
  auto options = loopback_options();
  options.max_clients = 2;
  options.overdue_floor = 50ms;
  start_server(options);
  run_client([&] {
    Client gone(port_), polling(port_);
    ASSERT_TRUE(gone.connect());
    ASSERT_TRUE(polling.connect());
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(gone.read_one(1), 1);
      EXPECT_EQ(polling.read_one(2), 2);
    }
    // `gone` falls silent; `polling` keeps its rhythm of a read every 20 ms.
    for (int i = 0; i < 20; ++i) {
      EXPECT_EQ(polling.read_one(2), 2);
      std::this_thread::sleep_for(20ms);
    }
    Client plc(port_);
    ASSERT_TRUE(plc.connect());
    EXPECT_EQ(plc.read_one(3), 3);
    EXPECT_EQ(polling.read_one(4), 4);
    EXPECT_EQ(gone.read_one(5), -1);
  });
  EXPECT_EQ(server_->stats().evicted.overdue, 1u);
  EXPECT_EQ(server_->stats().evicted.never_spoke, 0u);
}

// Beyond the connect rates, newcomers are closed at once: the open client is not even looked
// at, and a flood from one address does not use up the total for others.
TEST_F(ModbusTcpServerTest, ConnectRatesRefuseNewcomersBeforeAnyOpenClientIsTouched) {
  auto options = loopback_options();
  options.max_clients = 2;
  options.max_connects_per_second_per_address = 5;  // a burst of 10
  options.max_connects_per_second = 20;             // a burst of 40
  start_server(options);
  run_client([&] {
    Client plc(port_);
    ASSERT_TRUE(plc.connect());
    EXPECT_EQ(plc.read_one(1), 1);
    std::vector<std::unique_ptr<RawClient>> flood;
    for (int i = 0; i < 30; ++i) flood.push_back(std::make_unique<RawClient>(port_, "127.0.0.2"));
    for (int i = 0; i < 60; ++i)
      flood.push_back(
          std::make_unique<RawClient>(port_, ("127.0.0." + std::to_string(3 + i % 6)).c_str()));
    EXPECT_EQ(plc.read_one(2), 2);
    ASSERT_TRUE(wait_until([&] {
      return on_io([&] {
               return server_->stats().clients_accepted + server_->stats().clients_refused;
             }) >= 91;
    }));
  });
  const auto& stats = server_->stats();
  EXPECT_GE(stats.refused.rate_per_address, 20u);  // 127.0.0.2: at most 10 + refill let in
  EXPECT_GT(stats.refused.rate, 0u);               // the others together: beyond 40 + refill
  EXPECT_EQ(stats.clients_refused,
            stats.refused.rate_per_address + stats.refused.rate + stats.refused.no_idle_client);
}

TEST_F(ModbusTcpServerTest, PerAddressLimitRefusesTheExtraConnectionFromThatAddress) {
  auto options = loopback_options();
  options.max_clients_per_address = 1;
  start_server(options);
  run_client([&] {
    Client first(port_);
    ASSERT_TRUE(first.connect());
    EXPECT_EQ(first.read_one(1), 1);
    Client second(port_);
    second.connect();
    EXPECT_EQ(second.read_one(2), -1);
    EXPECT_EQ(first.read_one(3), 3);
  });
  EXPECT_EQ(server_->stats().clients_refused, 1u);
  EXPECT_EQ(server_->stats().clients_evicted, 0u);
}

TEST_F(ModbusTcpServerTest, BadMbapHeaderDropsTheConnectionUnanswered) {
  start_server();
  run_client([&] {
    const Bytes good = adu(1, 1, {0x03, 0x00, 0x00, 0x00, 0x01});
    const Bytes bad_protocol{0x00, 0x02, 0x00, 0x01, 0x00, 0x06,
                             0x01, 0x03, 0x00, 0x00, 0x00, 0x01};
    const Bytes zero_length{0x00, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01};
    const Bytes too_long{0x00, 0x04, 0x00, 0x00, 0x01, 0x00, 0x01};  // 256
    for (const Bytes& bad : {bad_protocol, zero_length, too_long}) {
      RawClient raw(port_);
      ASSERT_TRUE(raw.connected());
      ASSERT_TRUE(raw.send(bad));
      Bytes received;
      EXPECT_TRUE(raw.wait_closed(2s, &received));
      EXPECT_TRUE(received.empty());
    }
    // A good request ahead of the bad one in the same segment is still answered.
    RawClient raw(port_);
    ASSERT_TRUE(raw.send(cat({good, bad_protocol})));
    Bytes received;
    EXPECT_TRUE(raw.wait_closed(2s, &received));
    EXPECT_EQ(received, (Bytes{0, 1, 0, 0, 0, 5, 1, 0x03, 0x02, 0x00, 0x00}));
  });
  EXPECT_EQ(server_->stats().framing_errors, 4u);
}

TEST_F(ModbusTcpServerTest, HandlerSwapKeepsConnectionsAndFinishesWritesInProgress) {
  start_server();
  const auto old_handler = handler_;
  const auto new_handler = std::make_shared<FakeHandler>(io_.get_executor(), 5000);
  run_clients({
      [&] {
        Client writer(port_);
        writer.set_response_timeout(20s);
        ASSERT_TRUE(writer.connect());
        EXPECT_EQ(modbus_write_register(writer.get(), FakeHandler::slow_address, 77), 1);
      },
      [&] {
        Client reader(port_);
        ASSERT_TRUE(reader.connect());
        EXPECT_EQ(reader.read_one(0), 0);
        EXPECT_TRUE(wait_until([&] { return old_handler->slow_writes_pending == 1; }));
        on_io([&] { server_->set_handler(new_handler); });
        EXPECT_EQ(reader.read_one(0), 5000);  // same connection, new map
        asio::post(io_, [&] { old_handler->release_slow_writes(); });
      },
  });
  EXPECT_EQ(old_handler->holding[FakeHandler::slow_address], 77);
  EXPECT_EQ(new_handler->holding[FakeHandler::slow_address], 5000 + FakeHandler::slow_address);
  EXPECT_EQ(server_->stats().clients_accepted, 2u);
}

TEST_F(ModbusTcpServerTest, StopClosesListenerAndClientsAndLeavesNoWork) {
  start_server();
  run_client([&] {
    RawClient idle(port_);
    ASSERT_TRUE(idle.connected());
    Client c(port_);
    ASSERT_TRUE(c.connect());
    EXPECT_EQ(c.read_one(1), 1);
    on_io([&] { server_->stop(); });
    EXPECT_TRUE(idle.wait_closed(2s));
    EXPECT_EQ(c.read_one(1), -1);
    RawClient late(port_);
    EXPECT_FALSE(late.connected());
  });
  io_.restart();
  const auto start = Clock::now();
  io_.run_for(5s);  // returns as soon as nothing is left: no coroutine or timer leaked
  EXPECT_LT(Clock::now() - start, 1s);
  EXPECT_EQ(server_->stats().clients_connected, 0u);
}

TEST_F(ModbusTcpServerTest, AllowListDeniesClients) {
  std::vector<asio::ip::address> asked;
  auto options = loopback_options();
  options.allow_client = [&](const asio::ip::address& address) {
    asked.push_back(address);
    return false;
  };
  start_server(options);
  run_client([&] {
    Client c(port_);
    c.connect();
    EXPECT_EQ(c.read_one(1), -1);
  });
  EXPECT_EQ(server_->stats().clients_denied, 1u);
  EXPECT_EQ(server_->stats().clients_accepted, 0u);
  ASSERT_EQ(asked.size(), 1u);
  EXPECT_EQ(asked[0], asio::ip::make_address("127.0.0.1"));
}

TEST_F(ModbusTcpServerTest, ReconfigureAppliesTheAllowListToOpenClients) {
  start_server();
  run_client([&] {
    Client c(port_);
    ASSERT_TRUE(c.connect());
    EXPECT_EQ(c.read_one(1), 1);
    EXPECT_FALSE(on_io([&] {
      auto moved = options_;
      moved.endpoint.port(static_cast<std::uint16_t>(port_ + 1));
      return server_->reconfigure(moved);
    }));
    EXPECT_EQ(c.read_one(1), 1);
    EXPECT_TRUE(on_io([&] {
      auto denying = options_;  // same configured endpoint (port 0)
      denying.allow_client = [](const asio::ip::address&) { return false; };
      return server_->reconfigure(denying);
    }));
    EXPECT_EQ(c.read_one(1), -1);
    EXPECT_TRUE(wait_until([&] { return connected_clients() == 0; }));
  });
}

TEST_F(ModbusTcpServerTest, DualStackListenerServesIpv4AndIpv6) {
  std::vector<asio::ip::address> asked;
  auto options = loopback_options();
  options.endpoint = {asio::ip::tcp::v6(), 0};
  options.allow_client = [&](const asio::ip::address& address) {
    asked.push_back(address);
    return true;
  };
  try {
    start_server(options);
  } catch (const boost::system::system_error& e) {
    GTEST_SKIP() << "no IPv6 on this host: " << e.what();
  }
  run_client([&] {
    Client v4(port_);
    ASSERT_TRUE(v4.connect());
    EXPECT_EQ(v4.read_one(4), 4);
    Client v6(port_, 1, "::1");
    ASSERT_TRUE(v6.connect());
    EXPECT_EQ(v6.read_one(6), 6);
  });
  ASSERT_EQ(asked.size(), 2u);
  EXPECT_EQ(asked[0], asio::ip::make_address("127.0.0.1"));  // not ::ffff:127.0.0.1
  EXPECT_EQ(asked[1], asio::ip::make_address("::1"));
}

TEST_F(ModbusTcpServerTest, StatsCountRequestsAndExceptionsPerFunction) {
  start_server();
  run_client([&] {
    Client c(port_);
    ASSERT_TRUE(c.connect());
    for (int i = 0; i < 3; ++i) EXPECT_EQ(c.read_one(i), i);
    EXPECT_EQ(c.read_one(FakeHandler::failed_address), -1);
    EXPECT_EQ(modbus_write_register(c.get(), 1, 1), 1);
    EXPECT_EQ(modbus_write_register(c.get(), 2, 2), 1);
    RawClient raw(port_);
    ASSERT_TRUE(raw.send(adu(9, 1, {0x08, 0x00, 0x00, 0x00, 0x00})));
    EXPECT_EQ(raw.receive(9).size(), 9u);
  });
  const ModbusTcpServerStats& stats = server_->stats();
  EXPECT_EQ(stats.functions[0x03].requests, 4u);
  EXPECT_EQ(stats.functions[0x03].exceptions, 1u);
  EXPECT_EQ(stats.functions[0x06].requests, 2u);
  EXPECT_EQ(stats.functions[0x06].exceptions, 0u);
  EXPECT_EQ(stats.functions[0x08].requests, 1u);
  EXPECT_EQ(stats.functions[0x08].exceptions, 1u);
  EXPECT_EQ(stats.clients_accepted, 2u);
}

TEST_F(ModbusTcpServerTest, WithoutAHandlerRequestsGetGatewayPathUnavailable) {
  handler_.reset();
  start_server();
  run_client([&] {
    Client c(port_);
    ASSERT_TRUE(c.connect());
    EXPECT_EQ(c.read_one(1), -1);
    EXPECT_EQ(errno, EMBXGPATH);
  });
}

}  // namespace
}  // namespace fieldgate::modbus
