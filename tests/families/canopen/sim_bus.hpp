// A test rig around the CANopen simulator's network (sim/canopen) with frames in memory and
// injected time: it sends frames written in cansend/candump text, collects what the nodes send
// and drives SDO transfers and the CiA 402 drive through them. It drives the simulator only,
// never the driver (drivers/canopen), so the simulator's own tests stay independent of it.
#pragma once

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "network.hpp"

namespace fieldgate::sim::canopen {

// A node configuration whose heartbeat producer time (0x1017) at power-up is ms.
inline NodeConfig with_heartbeat_ms(std::uint16_t ms) {
  NodeConfig config;
  config.heartbeat_ms = ms;
  return config;
}

class SimBus {
 public:
  explicit SimBus(NodeConfig config, std::vector<std::uint8_t> ids = {2})
      : net_(config, [this](const CanFrame& f) { out_.push_back(to_string(f)); }) {
    for (auto id : ids) net_.add_node(id, now_);
  }

  Network& net() { return net_; }
  Node& node(std::uint8_t id = 2) { return *net_.node(id); }
  TimePoint now() const { return now_; }

  void advance(Clock::duration d) {
    // Advance the way the socket loop does: wake at each deadline on the way. After a wake-up
    // everything due is done, so the next deadline must lie ahead.
    const TimePoint end = now_ + d;
    while (true) {
      now_ = std::min(end, std::max(now_, net_.next_deadline()));
      net_.advance(now_);
      if (now_ == end) break;
      if (net_.next_deadline() <= now_) {
        ADD_FAILURE() << "next deadline is not after the time just served";
        break;
      }
    }
  }

  // Advance waking at each deadline but never sooner than 1 ms after the last wake-up, like a
  // loop with a millisecond tick; due work may wait up to 1 ms.
  void advance_at_least_1ms_apart(Clock::duration d) {
    const TimePoint end = now_ + d;
    while (now_ < end) {
      now_ = std::min(end, std::max(now_ + std::chrono::milliseconds(1), net_.next_deadline()));
      net_.advance(now_);
    }
  }

  void send(const std::string& text) {
    auto frame = parse_frame(text);
    ASSERT_TRUE(frame) << text;
    net_.receive(*frame, now_);
  }

  // Everything sent since the last take().
  std::vector<std::string> take() { return std::exchange(out_, {}); }

  // Sends a frame and takes what the nodes sent back.
  std::vector<std::string> answer(const std::string& text) {
    send(text);
    return take();
  }

  // How many times frame was sent since the last take().
  std::size_t count(const std::string& frame) const {
    return static_cast<std::size_t>(std::count(out_.begin(), out_.end(), frame));
  }

  // Frames sent since the last take() whose COB-ID is id.
  std::vector<std::string> take(std::uint32_t id) {
    std::vector<std::string> match, rest;
    for (auto& f : out_) (parse_frame(f)->id == id ? match : rest).push_back(f);
    out_ = rest;
    return match;
  }

  // Sends an SDO request to node 2 and returns its single response ("" if none).
  std::string sdo(const std::string& request_bytes, std::uint8_t id = 2) {
    take(0x580u + id);
    send(fmt::format("{:03X}#{}", 0x600 + id, request_bytes));
    auto replies = take(0x580u + id);
    EXPECT_LE(replies.size(), 1u);
    return replies.empty() ? "" : replies.front();
  }

  std::uint32_t upload(std::uint16_t index, std::uint8_t sub, std::uint8_t id = 2) {
    const auto reply =
        sdo(fmt::format("40{:02X}{:02X}{:02X}00000000", index & 0xFF, index >> 8, sub), id);
    auto frame = parse_frame(reply);
    EXPECT_TRUE(frame && (frame->data[0] & 0xE3) == 0x43) << reply;
    if (!frame) return 0;
    return from_le<std::uint32_t>(std::span(frame->data).subspan(4, 4));
  }

  std::string download(std::uint16_t index, std::uint8_t sub, std::uint32_t value, int size,
                       std::uint8_t id = 2) {
    const std::uint8_t cmd = static_cast<std::uint8_t>(0x23 | (4 - size) << 2);
    return sdo(fmt::format("{:02X}{:02X}{:02X}{:02X}{:08X}", cmd, index & 0xFF, index >> 8, sub,
                           __builtin_bswap32(value)),
               id);
  }

  void controlword(std::uint16_t cw) {
    EXPECT_EQ(download(0x6040, 0, cw, 2), "582#6040600000000000");
  }
  std::uint16_t statusword() { return static_cast<std::uint16_t>(upload(0x6041, 0)); }
  std::int32_t position() { return static_cast<std::int32_t>(upload(0x6064, 0)); }

  // Profile position: a new target through the setpoint handshake, the controlword `setpoint`
  // (bit 4 up; bit 5 change immediately, bit 6 relative) and then 0x0F (bit 4 down).
  void new_setpoint(std::int32_t target, std::uint16_t setpoint = 0x1F) {
    download(0x607A, 0, static_cast<std::uint32_t>(target), 4);
    controlword(setpoint);
    controlword(0x0F);
  }

  // Homing mode: the method, then bit 4 up to start it.
  void start_homing(std::uint8_t method) {
    download(0x6098, 0, method, 1);
    controlword(0x1F);
  }

  // Up to operation enabled in the given mode of operation.
  void enable(std::int8_t mode) {
    advance(std::chrono::milliseconds(50));
    EXPECT_EQ(download(0x6060, 0, static_cast<std::uint8_t>(mode), 1), "582#6060600000000000");
    controlword(0x06);
    controlword(0x07);
    controlword(0x0F);
    EXPECT_EQ(node().drive().state(), DriveState::operation_enabled);
  }

  // Segmented upload driven segment by segment; returns the bytes, checks every toggle bit.
  std::string segmented_upload(std::uint16_t index, std::uint8_t sub) {
    const auto init = parse_frame(
        sdo(fmt::format("40{:02X}{:02X}{:02X}00000000", index & 0xFF, index >> 8, sub)));
    EXPECT_TRUE(init);
    EXPECT_EQ(init->data[0], 0x41);
    const auto size = from_le<std::uint32_t>(std::span(init->data).subspan(4, 4));
    std::string value;
    bool toggle = false;
    for (int guard = 0; guard < 100; ++guard) {
      const auto seg = parse_frame(sdo(toggle ? "7000000000000000" : "6000000000000000"));
      EXPECT_TRUE(seg);
      if (!seg) break;
      EXPECT_EQ(seg->data[0] & 0xE0, 0x00) << "server command specifier 0";
      EXPECT_EQ(bool(seg->data[0] & 0x10), toggle);
      const int n = 7 - ((seg->data[0] >> 1) & 0x07);
      value.append(seg->data.begin() + 1, seg->data.begin() + 1 + n);
      toggle = !toggle;
      if (seg->data[0] & 0x01) break;
    }
    EXPECT_EQ(value.size(), size);
    return value;
  }

 private:
  TimePoint now_ = TimePoint{} + std::chrono::hours(1);
  std::vector<std::string> out_;
  Network net_;
};

}  // namespace fieldgate::sim::canopen
