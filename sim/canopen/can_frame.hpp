// A classic CAN frame as the device logic sees it, independent of SocketCAN's struct can_frame.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>

namespace fieldgate::sim::canopen {

using Clock = std::chrono::steady_clock;
using TimePoint = Clock::time_point;

struct CanFrame {
  std::uint32_t id = 0;  // 11-bit identifier (COB-ID)
  std::uint8_t len = 0;
  bool rtr = false;
  std::array<std::uint8_t, 8> data{};

  static CanFrame make(std::uint32_t id, std::initializer_list<std::uint8_t> bytes);
  static CanFrame remote(std::uint32_t id);

  friend bool operator==(const CanFrame&, const CanFrame&) = default;
};

using FrameSink = std::function<void(const CanFrame&)>;
using LogSink = std::function<void(const std::string&)>;

// candump/cansend text: "602#4000100000000000", "702#R".
std::string to_string(const CanFrame& frame);
std::optional<CanFrame> parse_frame(std::string_view text);

}  // namespace fieldgate::sim::canopen
