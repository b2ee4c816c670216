// dispatch(): request PDU in, handler called, response PDU out. Spec examples end to end,
// and every way a handler can fail.
#include "gateway/modbus/request_handler.hpp"

#include <gtest/gtest.h>

#include <functional>
#include <stdexcept>
#include <string>
#include <utility>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

namespace fieldgate::modbus {
namespace {

using Bytes = std::vector<std::uint8_t>;

struct Call {
  std::string what;
  std::uint8_t unit;
  std::uint16_t address;
  std::uint16_t count;
  std::vector<std::uint16_t> registers;
  std::vector<bool> bits;
};

class RecordingHandler : public RequestHandler {
 public:
  ReadBitsResult read_bits(std::uint8_t unit, BitTable table, std::uint16_t address,
                           std::uint16_t count) override {
    record(table == BitTable::coils ? "read coils" : "read discrete inputs", unit, address, count);
    if (on_read_bits) return on_read_bits(address, count);
    return std::vector<bool>(count, false);
  }
  ReadRegistersResult read_registers(std::uint8_t unit, RegisterTable table, std::uint16_t address,
                                     std::uint16_t count) override {
    record(table == RegisterTable::holding_registers ? "read holding" : "read input", unit, address,
           count);
    if (on_read_registers) return on_read_registers(address, count);
    return std::vector<std::uint16_t>(count, 0);
  }
  asio::awaitable<WriteResult> write_registers(std::uint8_t unit, std::uint16_t address,
                                               std::span<const std::uint16_t> values) override {
    record("write registers", unit, address, values.size(), {values.begin(), values.end()});
    if (throw_on_write) throw std::runtime_error("bus gone");
    co_return write_result;
  }
  asio::awaitable<WriteResult> write_coils(std::uint8_t unit, std::uint16_t address,
                                           std::vector<bool> values) override {
    record("write coils", unit, address, values.size(), {}, values);
    if (throw_on_write) throw std::runtime_error("bus gone");
    co_return write_result;
  }

  void record(std::string what, std::uint8_t unit, std::uint16_t address, std::size_t count,
              std::vector<std::uint16_t> registers = {}, std::vector<bool> bits = {}) {
    calls.push_back({std::move(what), unit, address, static_cast<std::uint16_t>(count),
                     std::move(registers), std::move(bits)});
  }

  std::vector<Call> calls;
  std::function<ReadBitsResult(std::uint16_t, std::uint16_t)> on_read_bits;
  std::function<ReadRegistersResult(std::uint16_t, std::uint16_t)> on_read_registers;
  WriteResult write_result;
  bool throw_on_write = false;
};

Bytes run_dispatch(RequestHandler& handler, const Bytes& pdu, std::uint8_t unit = 1) {
  asio::io_context io;
  auto response = asio::co_spawn(io, dispatch(handler, unit, pdu), asio::use_future);
  io.run();
  return response.get();
}

std::vector<bool> bits_of(const Bytes& bytes, std::size_t count) {
  std::vector<bool> bits(count);
  for (std::size_t i = 0; i < count; ++i) bits[i] = (bytes[i / 8] >> (i % 8)) & 1;
  return bits;
}

TEST(DispatchSpecExample, ReadCoils) {
  RecordingHandler h;
  h.on_read_bits = [](std::uint16_t, std::uint16_t count) {
    return bits_of({0xCD, 0x6B, 0x05}, count);
  };
  EXPECT_EQ(run_dispatch(h, {0x01, 0x00, 0x13, 0x00, 0x13}), (Bytes{0x01, 0x03, 0xCD, 0x6B, 0x05}));
  ASSERT_EQ(h.calls.size(), 1u);
  EXPECT_EQ(h.calls[0].what, "read coils");
  EXPECT_EQ(h.calls[0].address, 19);
  EXPECT_EQ(h.calls[0].count, 19);
}

TEST(DispatchSpecExample, ReadDiscreteInputs) {
  RecordingHandler h;
  h.on_read_bits = [](std::uint16_t, std::uint16_t count) {
    return bits_of({0xAC, 0xDB, 0x35}, count);
  };
  EXPECT_EQ(run_dispatch(h, {0x02, 0x00, 0xC4, 0x00, 0x16}), (Bytes{0x02, 0x03, 0xAC, 0xDB, 0x35}));
  EXPECT_EQ(h.calls.at(0).what, "read discrete inputs");
}

TEST(DispatchSpecExample, ReadHoldingRegisters) {
  RecordingHandler h;
  h.on_read_registers = [](std::uint16_t address, std::uint16_t) -> ReadRegistersResult {
    if (address != 107) return ExceptionCode::illegal_data_address;
    return std::vector<std::uint16_t>{0x022B, 0x0000, 0x0064};
  };
  EXPECT_EQ(run_dispatch(h, {0x03, 0x00, 0x6B, 0x00, 0x03}),
            (Bytes{0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64}));
  EXPECT_EQ(h.calls.at(0).what, "read holding");
}

TEST(DispatchSpecExample, ReadInputRegisters) {
  RecordingHandler h;
  h.on_read_registers = [](std::uint16_t, std::uint16_t) {
    return std::vector<std::uint16_t>{0x000A};
  };
  EXPECT_EQ(run_dispatch(h, {0x04, 0x00, 0x08, 0x00, 0x01}), (Bytes{0x04, 0x02, 0x00, 0x0A}));
  EXPECT_EQ(h.calls.at(0).what, "read input");
}

TEST(DispatchSpecExample, WriteSingleCoilGoesToWriteCoils) {
  RecordingHandler h;
  EXPECT_EQ(run_dispatch(h, {0x05, 0x00, 0xAC, 0xFF, 0x00}), (Bytes{0x05, 0x00, 0xAC, 0xFF, 0x00}));
  ASSERT_EQ(h.calls.size(), 1u);
  EXPECT_EQ(h.calls[0].what, "write coils");
  EXPECT_EQ(h.calls[0].address, 172);
  EXPECT_EQ(h.calls[0].bits, std::vector<bool>{true});
}

TEST(DispatchSpecExample, WriteSingleRegisterGoesToWriteRegisters) {
  RecordingHandler h;
  EXPECT_EQ(run_dispatch(h, {0x06, 0x00, 0x01, 0x00, 0x03}), (Bytes{0x06, 0x00, 0x01, 0x00, 0x03}));
  ASSERT_EQ(h.calls.size(), 1u);
  EXPECT_EQ(h.calls[0].what, "write registers");
  EXPECT_EQ(h.calls[0].registers, std::vector<std::uint16_t>{3});
}

TEST(DispatchSpecExample, WriteMultipleCoils) {
  RecordingHandler h;
  EXPECT_EQ(run_dispatch(h, {0x0F, 0x00, 0x13, 0x00, 0x0A, 0x02, 0xCD, 0x01}),
            (Bytes{0x0F, 0x00, 0x13, 0x00, 0x0A}));
  EXPECT_EQ(h.calls.at(0).bits,
            (std::vector<bool>{true, false, true, true, false, false, true, true, true, false}));
}

TEST(DispatchSpecExample, WriteMultipleRegisters) {
  RecordingHandler h;
  EXPECT_EQ(run_dispatch(h, {0x10, 0x00, 0x01, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01, 0x02}),
            (Bytes{0x10, 0x00, 0x01, 0x00, 0x02}));
  EXPECT_EQ(h.calls.at(0).registers, (std::vector<std::uint16_t>{0x000A, 0x0102}));
}

TEST(DispatchSpecExample, ReadWriteMultipleRegistersWritesFirst) {
  RecordingHandler h;
  h.on_read_registers = [](std::uint16_t, std::uint16_t) {
    return std::vector<std::uint16_t>{0x00FE, 0x0ACD, 0x0001, 0x0003, 0x000D, 0x00FF};
  };
  EXPECT_EQ(
      run_dispatch(h, {0x17, 0x00, 0x03, 0x00, 0x06, 0x00, 0x0E, 0x00, 0x03, 0x06, 0x00, 0xFF, 0x00,
                       0xFF, 0x00, 0xFF}),
      (Bytes{0x17, 0x0C, 0x00, 0xFE, 0x0A, 0xCD, 0x00, 0x01, 0x00, 0x03, 0x00, 0x0D, 0x00, 0xFF}));
  ASSERT_EQ(h.calls.size(), 2u);
  EXPECT_EQ(h.calls[0].what, "write registers");
  EXPECT_EQ(h.calls[0].address, 14);
  EXPECT_EQ(h.calls[0].registers, (std::vector<std::uint16_t>{0xFF, 0xFF, 0xFF}));
  EXPECT_EQ(h.calls[1].what, "read holding");
  EXPECT_EQ(h.calls[1].address, 3);
  EXPECT_EQ(h.calls[1].count, 6);
}

TEST(Dispatch, UnitIsPassedThrough) {
  RecordingHandler h;
  for (int unit : {0, 1, 17, 247, 255}) {
    run_dispatch(h, {0x03, 0x00, 0x00, 0x00, 0x01}, static_cast<std::uint8_t>(unit));
    run_dispatch(h, {0x06, 0x00, 0x00, 0x00, 0x01}, static_cast<std::uint8_t>(unit));
    EXPECT_EQ(h.calls.at(h.calls.size() - 2).unit, unit);
    EXPECT_EQ(h.calls.back().unit, unit);
  }
}

TEST(Dispatch, ParseErrorsNeverReachTheHandler) {
  RecordingHandler h;
  EXPECT_EQ(run_dispatch(h, {0x08, 0x00, 0x00, 0x12, 0x34}), (Bytes{0x88, 0x01}));
  EXPECT_EQ(run_dispatch(h, {0x03, 0x00, 0x00, 0x00, 0x7E}), (Bytes{0x83, 0x03}));
  EXPECT_EQ(run_dispatch(h, {0x01, 0xFF, 0xFF, 0x00, 0x02}), (Bytes{0x81, 0x02}));
  EXPECT_EQ(run_dispatch(h, {0x05, 0x00, 0x01, 0x12, 0x34}), (Bytes{0x85, 0x03}));
  EXPECT_EQ(run_dispatch(h, {}), (Bytes{0x80, 0x01}));
  EXPECT_TRUE(h.calls.empty());
}

TEST(Dispatch, ReadExceptionsFromTheHandler) {
  for (ExceptionCode code :
       {ExceptionCode::illegal_data_address, ExceptionCode::server_device_failure,
        ExceptionCode::server_busy, ExceptionCode::gateway_path_unavailable,
        ExceptionCode::gateway_target_failed}) {
    RecordingHandler h;
    h.on_read_bits = [code](std::uint16_t, std::uint16_t) { return code; };
    h.on_read_registers = [code](std::uint16_t, std::uint16_t) { return code; };
    const auto c = static_cast<std::uint8_t>(code);
    EXPECT_EQ(run_dispatch(h, {0x01, 0, 0, 0, 1}), (Bytes{0x81, c}));
    EXPECT_EQ(run_dispatch(h, {0x02, 0, 0, 0, 1}), (Bytes{0x82, c}));
    EXPECT_EQ(run_dispatch(h, {0x03, 0, 0, 0, 1}), (Bytes{0x83, c}));
    EXPECT_EQ(run_dispatch(h, {0x04, 0, 0, 0, 1}), (Bytes{0x84, c}));
    EXPECT_EQ(run_dispatch(h, {0x17, 0, 0, 0, 1, 0, 0, 0, 1, 2, 0, 0}), (Bytes{0x97, c}));
  }
}

TEST(Dispatch, WriteExceptionsFromTheHandler) {
  for (ExceptionCode code :
       {ExceptionCode::illegal_data_address,
        ExceptionCode::illegal_data_value,  // e.g. half a 32-bit value
        ExceptionCode::server_device_failure, ExceptionCode::gateway_target_failed}) {
    RecordingHandler h;
    h.write_result = code;
    const auto c = static_cast<std::uint8_t>(code);
    EXPECT_EQ(run_dispatch(h, {0x05, 0, 0, 0xFF, 0}), (Bytes{0x85, c}));
    EXPECT_EQ(run_dispatch(h, {0x06, 0, 0, 0, 1}), (Bytes{0x86, c}));
    EXPECT_EQ(run_dispatch(h, {0x0F, 0, 0, 0, 1, 1, 1}), (Bytes{0x8F, c}));
    EXPECT_EQ(run_dispatch(h, {0x10, 0, 0, 0, 1, 2, 0, 1}), (Bytes{0x90, c}));
    // 0x17: a failed write is not followed by the read.
    EXPECT_EQ(run_dispatch(h, {0x17, 0, 0, 0, 1, 0, 0, 0, 1, 2, 0, 0}), (Bytes{0x97, c}));
    EXPECT_EQ(h.calls.back().what, "write registers");
  }
}

TEST(Dispatch, WrongNumberOfValuesIsADeviceFailure) {
  RecordingHandler h;
  h.on_read_bits = [](std::uint16_t, std::uint16_t count) {
    return std::vector<bool>(count + 1u, true);
  };
  h.on_read_registers = [](std::uint16_t, std::uint16_t count) {
    return std::vector<std::uint16_t>(count - 1u, 0);
  };
  EXPECT_EQ(run_dispatch(h, {0x01, 0, 0, 0, 8}), (Bytes{0x81, 0x04}));
  EXPECT_EQ(run_dispatch(h, {0x04, 0, 0, 0, 2}), (Bytes{0x84, 0x04}));
}

TEST(Dispatch, ThrowingHandlerIsADeviceFailure) {
  RecordingHandler h;
  h.throw_on_write = true;
  EXPECT_EQ(run_dispatch(h, {0x06, 0, 0, 0, 1}), (Bytes{0x86, 0x04}));
  EXPECT_EQ(run_dispatch(h, {0x0F, 0, 0, 0, 1, 1, 1}), (Bytes{0x8F, 0x04}));
  h.on_read_registers = [](std::uint16_t, std::uint16_t) -> ReadRegistersResult {
    throw std::runtime_error("image gone");
  };
  EXPECT_EQ(run_dispatch(h, {0x03, 0, 0, 0, 1}), (Bytes{0x83, 0x04}));
}

TEST(Dispatch, WriteResultDefaultsToSuccess) {
  EXPECT_TRUE(WriteResult{}.ok());
  EXPECT_TRUE(WriteResult::success().ok());
  const WriteResult failed = ExceptionCode::gateway_target_failed;
  EXPECT_FALSE(failed.ok());
  EXPECT_EQ(failed.exception(), ExceptionCode::gateway_target_failed);
}

}  // namespace
}  // namespace fieldgate::modbus
