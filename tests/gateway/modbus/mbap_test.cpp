// MBAP header and the bounded stream framer: whole, split, pipelined and malformed input.
#include "gateway/modbus/mbap.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <vector>

namespace fieldgate::modbus {
namespace {

using Bytes = std::vector<std::uint8_t>;

// Spec-style read holding registers ADU: transaction 0x0001, unit 0x11.
const Bytes read_adu{0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x11, 0x03, 0x00, 0x6B, 0x00, 0x03};

void feed(MbapFramer& framer, std::span<const std::uint8_t> bytes) {
  while (!bytes.empty()) {
    auto space = framer.free_space();
    ASSERT_FALSE(space.empty());
    const std::size_t n = std::min(space.size(), bytes.size());
    std::memcpy(space.data(), bytes.data(), n);
    framer.commit(n);
    bytes = bytes.subspan(n);
  }
}

TEST(Mbap, DecodeHeader) {
  const MbapHeader h = decode_mbap_header(std::span<const std::uint8_t, 7>(read_adu.data(), 7));
  EXPECT_EQ(h, (MbapHeader{0x0001, 0x0000, 0x0006, 0x11}));
}

TEST(Mbap, EncodeAdu) {
  Bytes out;
  const Bytes pdu{0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64};
  encode_adu(0xBEEF, 0x11, pdu, out);
  EXPECT_EQ(out, (Bytes{0xBE, 0xEF, 0x00, 0x00, 0x00, 0x09, 0x11, 0x03, 0x06, 0x02, 0x2B, 0x00,
                        0x00, 0x00, 0x64}));
  EXPECT_EQ(max_adu_size, 260u);
}

TEST(MbapFramer, WholeFrame) {
  MbapFramer framer;
  feed(framer, read_adu);
  MbapFramer::Frame frame;
  ASSERT_EQ(framer.next(frame), MbapFramer::Status::frame);
  EXPECT_EQ(frame.header.transaction_id, 1);
  EXPECT_EQ(frame.header.unit_id, 0x11);
  EXPECT_EQ(Bytes(frame.pdu.begin(), frame.pdu.end()), (Bytes{0x03, 0x00, 0x6B, 0x00, 0x03}));
  EXPECT_EQ(framer.next(frame), MbapFramer::Status::need_more);
  EXPECT_TRUE(framer.empty());
}

TEST(MbapFramer, ByteByByte) {
  MbapFramer framer;
  MbapFramer::Frame frame;
  for (std::size_t i = 0; i + 1 < read_adu.size(); ++i) {
    feed(framer, std::span(read_adu).subspan(i, 1));
    ASSERT_EQ(framer.next(frame), MbapFramer::Status::need_more) << i;
    EXPECT_FALSE(framer.empty());
  }
  feed(framer, std::span(read_adu).last(1));
  ASSERT_EQ(framer.next(frame), MbapFramer::Status::frame);
  EXPECT_EQ(frame.pdu.size(), 5u);
}

TEST(MbapFramer, PipelinedFramesInOneChunk) {
  Bytes stream;
  for (std::uint8_t tid = 1; tid <= 3; ++tid) {
    Bytes adu = read_adu;
    adu[1] = tid;
    stream.insert(stream.end(), adu.begin(), adu.end());
  }
  stream.insert(stream.end(), read_adu.begin(), read_adu.begin() + 3);  // start of a 4th
  MbapFramer framer;
  feed(framer, stream);
  MbapFramer::Frame frame;
  for (std::uint8_t tid = 1; tid <= 3; ++tid) {
    ASSERT_EQ(framer.next(frame), MbapFramer::Status::frame);
    EXPECT_EQ(frame.header.transaction_id, tid);
  }
  EXPECT_EQ(framer.next(frame), MbapFramer::Status::need_more);
  EXPECT_EQ(framer.buffered(), 3u);
}

TEST(MbapFramer, LargestAdusStreamedThroughTheBoundedBuffer) {
  // 50 maximum-size ADUs in 97-byte chunks: the buffer never grows and never runs out of room.
  Bytes adu(max_adu_size, 0xA5);
  adu[2] = adu[3] = 0;
  adu[4] = 0x00;
  adu[5] = 0xFE;  // length 254
  Bytes stream;
  for (int i = 0; i < 50; ++i) stream.insert(stream.end(), adu.begin(), adu.end());

  MbapFramer framer;
  MbapFramer::Frame frame;
  int frames = 0;
  for (std::size_t pos = 0; pos < stream.size(); pos += 97) {
    feed(framer, std::span(stream).subspan(pos, std::min<std::size_t>(97, stream.size() - pos)));
    MbapFramer::Status status;
    while ((status = framer.next(frame)) == MbapFramer::Status::frame) {
      EXPECT_EQ(frame.pdu.size(), max_pdu_size);
      ++frames;
    }
    ASSERT_EQ(status, MbapFramer::Status::need_more);
    ASSERT_LT(framer.buffered(), max_adu_size);
  }
  EXPECT_EQ(frames, 50);
}

TEST(MbapFramer, BadProtocolIdIsReportedBeforeTheLength) {
  MbapFramer framer;
  feed(framer, Bytes{0x00, 0x01, 0x00, 0x01});
  MbapFramer::Frame frame;
  EXPECT_EQ(framer.next(frame), MbapFramer::Status::bad_protocol_id);
}

TEST(MbapFramer, BadLengths) {
  for (std::uint16_t length : {0, 1, 255, 256, 0xFFFF}) {
    MbapFramer framer;
    feed(framer, Bytes{0x00, 0x01, 0x00, 0x00, static_cast<std::uint8_t>(length >> 8),
                       static_cast<std::uint8_t>(length)});
    MbapFramer::Frame frame;
    EXPECT_EQ(framer.next(frame), MbapFramer::Status::bad_length) << length;
  }
}

TEST(MbapFramer, ShortestFrameHasAOneBytePdu) {
  MbapFramer framer;
  feed(framer, Bytes{0x00, 0x07, 0x00, 0x00, 0x00, 0x02, 0xFF, 0x08});
  MbapFramer::Frame frame;
  ASSERT_EQ(framer.next(frame), MbapFramer::Status::frame);
  EXPECT_EQ(frame.header.unit_id, 0xFF);
  EXPECT_EQ(Bytes(frame.pdu.begin(), frame.pdu.end()), Bytes{0x08});
}

}  // namespace
}  // namespace fieldgate::modbus
