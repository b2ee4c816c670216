#include "drivers/transport/can_frame.hpp"

#include <fmt/format.h>
#include <linux/can.h>
#include <linux/can/error.h>

#include <algorithm>
#include <charconv>

namespace fieldgate {

CanFrame CanFrame::make(uint32_t id, std::initializer_list<uint8_t> bytes) {
  CanFrame f;
  f.id = id;
  f.len = static_cast<uint8_t>(std::min<std::size_t>(bytes.size(), 8));
  std::copy_n(bytes.begin(), f.len, f.data.begin());
  return f;
}

std::string to_string(const CanFrame& frame) {
  std::string out = frame.error ? fmt::format("{:08X}#", frame.id | CAN_ERR_FLAG)
                                : fmt::format("{:03X}#", frame.id);
  if (frame.rtr) return out + "R";
  for (uint8_t i = 0; i < frame.len; ++i) out += fmt::format("{:02X}", frame.data[i]);
  return out;
}

std::optional<CanFrame> parse_frame(std::string_view text) {
  const auto hash = text.find('#');
  if (hash == std::string_view::npos || hash == 0) return std::nullopt;
  const std::string_view id_text = text.substr(0, hash);
  std::string_view data = text.substr(hash + 1);
  uint32_t id = 0;
  auto [end, ec] = std::from_chars(id_text.data(), id_text.data() + id_text.size(), id, 16);
  if (ec != std::errc{} || end != id_text.data() + id_text.size()) return std::nullopt;
  CanFrame f;
  if (id_text.size() == 8 && (id & CAN_ERR_FLAG)) {
    f.error = true;
    f.id = id & CAN_ERR_MASK;
  } else if (id_text.size() == 3 && id <= CAN_SFF_MASK) {
    f.id = id;
  } else {
    return std::nullopt;
  }
  if (data == "R") {
    f.rtr = true;
    return f;
  }
  if (data.size() % 2 != 0 || data.size() > 16) return std::nullopt;
  for (std::size_t i = 0; i < data.size(); i += 2) {
    uint8_t b = 0;
    auto [e, c] = std::from_chars(data.data() + i, data.data() + i + 2, b, 16);
    if (c != std::errc{} || e != data.data() + i + 2) return std::nullopt;
    f.data[f.len++] = b;
  }
  return f;
}

ErrorFrameInfo decode_error_frame(const CanFrame& frame) {
  ErrorFrameInfo info;
  if (!frame.error) return info;
  std::string parts;
  const auto add = [&](std::string_view what) {
    parts += parts.empty() ? "" : ", ";
    parts += what;
  };
  const uint32_t cls = frame.id;
  const uint8_t ctrl = frame.data[1];
  if (cls & CAN_ERR_BUSOFF) {
    info.bus_off = true;
    add("bus-off");
  }
  if (cls & CAN_ERR_RESTARTED) {
    info.restarted = true;
    add("controller restarted");
  }
  if (cls & CAN_ERR_CRTL) {
    if (ctrl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) {
      info.error_passive = true;
      add("error passive");
    }
    if (ctrl & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) {
      info.error_warning = true;
      add("error warning");
    }
    if (ctrl & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) {
      info.rx_overflow = (ctrl & CAN_ERR_CRTL_RX_OVERFLOW) != 0;
      add("controller buffer overflow");
    }
    if (ctrl & CAN_ERR_CRTL_ACTIVE) add("back to error active");
    if (ctrl == 0) add("controller problem");
  }
  if (cls & CAN_ERR_TX_TIMEOUT) add("transmit timeout");
  if (cls & CAN_ERR_LOSTARB) add("lost arbitration");
  if (cls & CAN_ERR_PROT) add("protocol violation");
  if (cls & CAN_ERR_TRX) add("transceiver problem");
  if (cls & CAN_ERR_ACK) add("no acknowledge");
  if (cls & CAN_ERR_BUSERROR) add("bus error");
  if (parts.empty()) add("unspecified error");
  info.text = std::move(parts);
  return info;
}

}  // namespace fieldgate
