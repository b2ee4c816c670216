// A classic CAN frame, independent of SocketCAN's struct can_frame, and the candump text form
// used in logs and test vectors. The transport's unit; CANopen (drivers/canopen) builds on it.
#pragma once

#include <array>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>

namespace fieldgate {

struct CanFrame {
  uint32_t id = 0;  // 11-bit COB-ID; for an error frame the error class bits (can/error.h)
  uint8_t len = 0;
  bool rtr = false;
  bool error = false;  // an error frame reported by the CAN controller or driver
  std::array<uint8_t, 8> data{};

  static CanFrame make(uint32_t id, std::initializer_list<uint8_t> bytes);

  friend bool operator==(const CanFrame&, const CanFrame&) = default;
};

// candump -L / cansend text: "602#4000100000000000", "702#R"; error frames as candump prints
// them, with CAN_ERR_FLAG in an 8-digit identifier ("20000040#0000000000000000").
std::string to_string(const CanFrame& frame);
std::optional<CanFrame> parse_frame(std::string_view text);

// What an error frame says (linux/can/error.h), for counters and one readable log line.
struct ErrorFrameInfo {
  bool bus_off = false;
  bool error_passive = false;  // controller reached error passive (rx or tx)
  bool error_warning = false;
  bool restarted = false;  // controller restarted after bus-off
  bool rx_overflow = false;
  std::string text;
};
ErrorFrameInfo decode_error_frame(const CanFrame& frame);

}  // namespace fieldgate
