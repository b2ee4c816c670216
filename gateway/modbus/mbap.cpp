#include "gateway/modbus/mbap.hpp"

#include <cassert>
#include <cstring>

namespace fieldgate::modbus {
namespace {

std::uint16_t get16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>((p[0] << 8) | p[1]);
}

}  // namespace

MbapHeader decode_mbap_header(std::span<const std::uint8_t, mbap_header_size> bytes) {
  return MbapHeader{get16(&bytes[0]), get16(&bytes[2]), get16(&bytes[4]), bytes[6]};
}

void encode_adu(std::uint16_t transaction_id, std::uint8_t unit_id,
                std::span<const std::uint8_t> pdu, std::vector<std::uint8_t>& out) {
  const auto length = static_cast<std::uint16_t>(pdu.size() + 1);
  const std::uint8_t header[mbap_header_size] = {static_cast<std::uint8_t>(transaction_id >> 8),
                                                 static_cast<std::uint8_t>(transaction_id & 0xFF),
                                                 0,
                                                 0,
                                                 static_cast<std::uint8_t>(length >> 8),
                                                 static_cast<std::uint8_t>(length & 0xFF),
                                                 unit_id};
  out.insert(out.end(), std::begin(header), std::end(header));
  out.insert(out.end(), pdu.begin(), pdu.end());
}

std::span<std::uint8_t> MbapFramer::free_space() {
  if (begin_ != 0) {
    std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  // next() rejects lengths above max_adu_size, so a pending partial frame leaves room.
  assert(end_ < capacity);
  return std::span<std::uint8_t>(buffer_).subspan(end_);
}

void MbapFramer::commit(std::size_t n) {
  assert(n <= capacity - end_);
  end_ += n;
}

MbapFramer::Status MbapFramer::next(Frame& frame) {
  const std::uint8_t* p = buffer_.data() + begin_;
  const std::size_t available = end_ - begin_;
  if (available >= 4 && get16(p + 2) != 0) return Status::bad_protocol_id;
  if (available < 6) return Status::need_more;
  const std::uint16_t length = get16(p + 4);
  if (length < min_mbap_length || length > max_mbap_length) return Status::bad_length;
  const std::size_t total = mbap_header_size - 1 + length;
  if (available < total) return Status::need_more;
  frame.header = decode_mbap_header(std::span<const std::uint8_t, mbap_header_size>(p, 7));
  frame.pdu = std::span<const std::uint8_t>(p + mbap_header_size, total - mbap_header_size);
  begin_ += total;
  return Status::frame;
}

}  // namespace fieldgate::modbus
