#include "sim/common/wire_pacing.hpp"

#include <algorithm>
#include <stdexcept>

namespace fieldgate::sim {

WireTiming::WireTiming(std::uint32_t baud, FrameFormat format) : baud_(baud), format_(format) {
  set_baud(baud);
}

void WireTiming::set_baud(std::uint32_t baud) {
  if (baud == 0) throw std::invalid_argument("baud rate must be positive");
  baud_ = baud;
}

std::chrono::nanoseconds WireTiming::wire_time(std::size_t characters) const {
  const auto bits = static_cast<std::uint64_t>(characters) * format_.bits_per_character();
  return std::chrono::nanoseconds(bits * 1'000'000'000ULL / baud_);
}

void ReceiveWire::first_byte(SimTime seen) {
  first_byte_ = std::max(seen, line_free_);
}

SimTime ReceiveWire::complete(std::size_t characters, SimTime read_at, const WireEmulation& wire) {
  if (!wire.enabled) {
    line_free_ = read_at;
    return read_at;
  }
  const SimTime on_wire = first_byte_ + wire.timing.wire_time(characters);
  line_free_ = std::max(on_wire, read_at);
  // Bytes already buffered behind this request start where this one ended.
  first_byte_ = line_free_;
  return line_free_;
}

SimTime PacedTransmitter::enqueue(SimTime start, std::string_view bytes, const WireTiming* timing) {
  start = std::max(start, line_free_);
  if (bytes.empty()) return start;
  if (timing == nullptr) {
    chunks_.push_back({start, std::string(bytes)});
    line_free_ = start;
    return start;
  }
  const auto per_char = timing->character_time();
  const std::size_t chunk_size = std::max<std::size_t>(
      1, per_char.count() > 0 ? static_cast<std::size_t>(granularity_ / per_char) : bytes.size());
  for (std::size_t begin = 0; begin < bytes.size(); begin += chunk_size) {
    const std::size_t end = std::min(bytes.size(), begin + chunk_size);
    // A character is usable by the receiver once its stop bit has left.
    chunks_.push_back(
        {start + timing->wire_time(end), std::string(bytes.substr(begin, end - begin))});
  }
  line_free_ = start + timing->wire_time(bytes.size());
  return line_free_;
}

void PacedTransmitter::release(SimTime now, std::string& out) {
  while (!chunks_.empty() && chunks_.front().due <= now) {
    out += chunks_.front().bytes;
    chunks_.pop_front();
  }
}

std::optional<SimTime> PacedTransmitter::next_due() const {
  if (chunks_.empty()) return std::nullopt;
  return chunks_.front().due;
}

}  // namespace fieldgate::sim
