// The RTU codec against the spec's and the CRC catalogue's vectors, and against libmodbus's
// RTU master on a PTY: frames it builds decode here, and frames built here it accepts.
#include "gateway/modbus/rtu_codec.hpp"

#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <future>
#include <string>
#include <vector>

#include "gateway/modbus/pdu.hpp"

namespace fieldgate::modbus {
namespace {

using Bytes = std::vector<std::uint8_t>;
using namespace std::chrono_literals;

Bytes with_crc(Bytes body) {
  Bytes out;
  encode_rtu_adu(body[0], std::span<const std::uint8_t>(body).subspan(1), out);
  return out;
}

TEST(RtuCodec, CrcCatalogueCheckValue) {
  // CRC-16/MODBUS of "123456789" is 0x4B37 (Williams/Greg Cook catalogue).
  const std::string text = "123456789";
  EXPECT_EQ(rtu_crc16(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size())),
            0x4B37);
}

TEST(RtuCodec, SpecExamplesLowByteFirst) {
  // Read 10 holding registers from unit 1 at 0: the frame every Modbus tutorial shows.
  EXPECT_EQ(with_crc({0x01, 0x03, 0x00, 0x00, 0x00, 0x0A}),
            (Bytes{0x01, 0x03, 0x00, 0x00, 0x00, 0x0A, 0xC5, 0xCD}));
  // Modbus over Serial Line V1.02 §6.2.2 example: 0x02 0x07 gives CRC 0x1241, sent 41 12.
  EXPECT_EQ(with_crc({0x02, 0x07}), (Bytes{0x02, 0x07, 0x41, 0x12}));
}

TEST(RtuCodec, DecodesAGoodFrame) {
  const Bytes adu = with_crc({0x11, 0x06, 0x00, 0x01, 0x00, 0x03});
  const auto r = decode_rtu_adu(adu);
  ASSERT_EQ(r.error, RtuFrameError::none);
  EXPECT_EQ(r.frame.unit, 0x11);
  EXPECT_EQ(Bytes(r.frame.pdu.begin(), r.frame.pdu.end()), (Bytes{0x06, 0x00, 0x01, 0x00, 0x03}));
}

TEST(RtuCodec, RejectsEveryFlippedBit) {
  const Bytes good = with_crc({0x05, 0x10, 0x00, 0x64, 0x00, 0x01, 0x02, 0x12, 0x34});
  for (std::size_t i = 0; i < good.size() * 8; ++i) {
    Bytes bad = good;
    bad[i / 8] ^= static_cast<std::uint8_t>(1u << (i % 8));
    // A flip in a length field may make it read as truncated; never as good.
    EXPECT_NE(decode_rtu_adu(bad).error, RtuFrameError::none) << "bit " << i;
  }
}

TEST(RtuCodec, SizeErrors) {
  EXPECT_EQ(decode_rtu_adu(Bytes{0x01, 0x03, 0xC5}).error, RtuFrameError::too_short);
  EXPECT_EQ(decode_rtu_adu(Bytes(257, 0x55)).error, RtuFrameError::too_long);
  const Bytes good = with_crc({0x01, 0x03, 0x00, 0x00, 0x00, 0x0A});
  // Cut short: the length the function code implies is not reached.
  EXPECT_EQ(decode_rtu_adu(std::span(good).first(6)).error, RtuFrameError::truncated);
  const Bytes write = with_crc({0x01, 0x10, 0x00, 0x00, 0x00, 0x02, 0x04, 1, 2, 3, 4});
  EXPECT_EQ(decode_rtu_adu(std::span(write).first(9)).error, RtuFrameError::truncated);
  // Two frames run together: long enough, CRC wrong.
  Bytes joined = good;
  joined.insert(joined.end(), good.begin(), good.end());
  EXPECT_EQ(decode_rtu_adu(joined).error, RtuFrameError::bad_crc);
}

TEST(RtuCodec, RequestSizes) {
  EXPECT_EQ(rtu_request_size(Bytes{0x01, 0x03}), 8u);
  EXPECT_EQ(rtu_request_size(Bytes{0x01, 0x10, 0, 0, 0, 2}), std::nullopt);
  EXPECT_EQ(rtu_request_size(Bytes{0x01, 0x10, 0, 0, 0, 2, 4}), 13u);
  EXPECT_EQ(rtu_request_size(Bytes{0x01, 0x17, 0, 0, 0, 1, 0, 0, 0, 1, 2}), 15u);
  EXPECT_EQ(rtu_request_size(Bytes{0x01, 0x2B, 0x0E}), 7u);
  EXPECT_EQ(rtu_request_size(Bytes{0x01, 0x41}), std::nullopt);
}

TEST(RtuCodec, IncompleteRequests) {
  const Bytes read = with_crc({0x01, 0x03, 0x00, 0x00, 0x00, 0x0A});
  EXPECT_TRUE(rtu_request_incomplete(std::span(read).first(1)));
  EXPECT_TRUE(rtu_request_incomplete(std::span(read).first(7)));
  EXPECT_FALSE(rtu_request_incomplete(read));
  EXPECT_TRUE(rtu_request_incomplete(Bytes{0x01, 0x10, 0x00, 0x00}));
  // An exception answer of another slave is shorter than a request but complete.
  EXPECT_FALSE(rtu_request_incomplete(with_crc({0x01, 0x83, 0x02})));
  // Unknown function codes: the silence decides.
  EXPECT_FALSE(rtu_request_incomplete(Bytes{0x01, 0x41, 0x00}));
}

TEST(RtuCodec, SilentInterval) {
  // 9600 8E1: 11 bits, 1145.8 us a character, t3.5 = 4010.4 us rounded up.
  EXPECT_EQ(rtu_silent_interval(9600, 11), std::chrono::microseconds(4011));
  EXPECT_EQ(rtu_silent_interval(19200, 11), std::chrono::microseconds(2006));
  EXPECT_EQ(rtu_silent_interval(38400, 11), std::chrono::microseconds(1750));
  EXPECT_EQ(rtu_silent_interval(115200, 10), std::chrono::microseconds(1750));
}

// A PTY: libmodbus's master opens the slave side, the test plays the server on the master side.
class Pty {
 public:
  Pty() {
    if (::openpty(&master_, &slave_, name_, nullptr, nullptr) != 0)
      throw std::runtime_error("openpty");
    termios tio{};
    ::tcgetattr(slave_, &tio);
    ::cfmakeraw(&tio);
    ::tcsetattr(slave_, TCSANOW, &tio);
  }
  ~Pty() {
    ::close(master_);
    ::close(slave_);
  }
  const char* name() const { return name_; }
  // Reads until `silence` passes without a byte (the frame's end, as a server would see it).
  Bytes read_frame(std::chrono::milliseconds first, std::chrono::milliseconds silence) {
    Bytes out;
    int timeout = static_cast<int>(first.count());
    for (;;) {
      pollfd p{master_, POLLIN, 0};
      if (::poll(&p, 1, timeout) <= 0) return out;
      std::uint8_t buf[300];
      const auto n = ::read(master_, buf, sizeof buf);
      if (n <= 0) return out;
      out.insert(out.end(), buf, buf + n);
      timeout = static_cast<int>(silence.count());
    }
  }
  void write(const Bytes& b) { ASSERT_EQ(::write(master_, b.data(), b.size()), ssize_t(b.size())); }

 private:
  int master_ = -1, slave_ = -1;
  char name_[128]{};
};

struct Master {
  explicit Master(const char* device) {
    ctx = modbus_new_rtu(device, 19200, 'E', 8, 1);
    if (!ctx || modbus_connect(ctx) != 0) throw std::runtime_error("libmodbus cannot open PTY");
    modbus_set_response_timeout(ctx, 2, 0);
  }
  ~Master() {
    modbus_close(ctx);
    modbus_free(ctx);
  }
  modbus_t* ctx;
};

TEST(RtuCodecLibmodbus, FramesLibmodbusSendsDecode) {
  Pty pty;
  Master m(pty.name());
  const std::uint8_t raws[][8] = {{0x07, 0x03, 0x00, 0x6B, 0x00, 0x03},
                                  {0xF7, 0x06, 0x00, 0x64, 0xFF, 0xFF},
                                  {0x00, 0x06, 0x00, 0x64, 0x00, 0x06}};
  for (const auto& raw : raws) {
    ASSERT_GT(modbus_send_raw_request(m.ctx, raw, 6), 0);
    const Bytes frame = pty.read_frame(1000ms, 20ms);
    ASSERT_EQ(frame.size(), 8u);
    const auto r = decode_rtu_adu(frame);
    ASSERT_EQ(r.error, RtuFrameError::none);
    EXPECT_EQ(r.frame.unit, raw[0]);
    EXPECT_EQ(Bytes(r.frame.pdu.begin(), r.frame.pdu.end()), Bytes(raw + 1, raw + 6));
    EXPECT_EQ(frame, with_crc(Bytes(raw, raw + 6)));
  }
}

TEST(RtuCodecLibmodbus, LibmodbusAcceptsOurResponses) {
  Pty pty;
  Master m(pty.name());
  modbus_set_slave(m.ctx, 9);
  auto reader = std::async(std::launch::async, [&] {
    std::uint16_t values[3] = {};
    const int n = modbus_read_registers(m.ctx, 0x20, 3, values);
    return std::pair{n, std::vector<std::uint16_t>(values, values + 3)};
  });
  const Bytes request = pty.read_frame(2000ms, 20ms);
  const auto r = decode_rtu_adu(request);
  ASSERT_EQ(r.error, RtuFrameError::none);
  ASSERT_EQ(r.frame.unit, 9);
  const std::uint16_t values[] = {0x1234, 0, 0xFFFF};
  Bytes response;
  encode_rtu_adu(9, encode_read_registers_response(FunctionCode::read_holding_registers, values),
                 response);
  pty.write(response);
  const auto [n, got] = reader.get();
  EXPECT_EQ(n, 3);
  EXPECT_EQ(got, (std::vector<std::uint16_t>{0x1234, 0, 0xFFFF}));
}

TEST(RtuCodecLibmodbus, LibmodbusRejectsACorruptedResponse) {
  Pty pty;
  Master m(pty.name());
  modbus_set_slave(m.ctx, 9);
  modbus_set_response_timeout(m.ctx, 0, 300000);
  auto reader = std::async(std::launch::async, [&] {
    std::uint16_t value = 0;
    return modbus_read_registers(m.ctx, 0x20, 1, &value);
  });
  ASSERT_EQ(decode_rtu_adu(pty.read_frame(2000ms, 20ms)).error, RtuFrameError::none);
  const std::uint16_t values[] = {0x1234};
  Bytes response;
  encode_rtu_adu(9, encode_read_registers_response(FunctionCode::read_holding_registers, values),
                 response);
  response.back() ^= 0x01;
  pty.write(response);
  EXPECT_EQ(reader.get(), -1);
}

}  // namespace
}  // namespace fieldgate::modbus
