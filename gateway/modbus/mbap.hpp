// Modbus TCP framing: the MBAP header and a bounded splitter for a client's byte stream.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "gateway/modbus/pdu.hpp"

namespace fieldgate::modbus {

inline constexpr std::size_t mbap_header_size = 7;
// The MBAP length field counts the unit id and the PDU.
inline constexpr std::uint16_t min_mbap_length = 2;
inline constexpr std::uint16_t max_mbap_length = 1 + max_pdu_size;
inline constexpr std::size_t max_adu_size = mbap_header_size - 1 + max_mbap_length;  // 260

struct MbapHeader {
  std::uint16_t transaction_id = 0;
  std::uint16_t protocol_id = 0;
  std::uint16_t length = 0;
  std::uint8_t unit_id = 0;
  bool operator==(const MbapHeader&) const = default;
};

MbapHeader decode_mbap_header(std::span<const std::uint8_t, mbap_header_size> bytes);

// Appends header + pdu to out; the length field is computed from the pdu.
void encode_adu(std::uint16_t transaction_id, std::uint8_t unit_id,
                std::span<const std::uint8_t> pdu, std::vector<std::uint8_t>& out);

// Splits a client's byte stream into ADUs in a fixed buffer: read into free_space(), commit(),
// then take frames with next() until it says need_more. A bad protocol id or length is
// reported as soon as those header bytes arrive; the stream cannot be resynchronised after it.
class MbapFramer {
 public:
  // Room for several pipelined requests; any single ADU always fits.
  static constexpr std::size_t capacity = 4 * max_adu_size;

  enum class Status { need_more, frame, bad_protocol_id, bad_length };

  struct Frame {
    MbapHeader header;
    std::span<const std::uint8_t> pdu;  // valid until the next free_space()
  };

  // Compacts the buffer and returns where the next read may write; never empty.
  std::span<std::uint8_t> free_space();
  void commit(std::size_t n);
  Status next(Frame& frame);

  bool empty() const { return begin_ == end_; }
  std::size_t buffered() const { return end_ - begin_; }

 private:
  std::array<std::uint8_t, capacity> buffer_{};
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
};

}  // namespace fieldgate::modbus
