// Link::read_frame with a deadline already passed (a family's flush before a request): it takes
// what the OS holds and ends, without starting a read or a timer on the event loop.
#include <gtest/gtest.h>

#include "held_bytes.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;
using test::HeldBytes;
using test::kNoWait;
using test::read_now;

TEST(LinkNoWait, TakesAWholeFrameTheOsHolds) {
  HeldBytes device;
  device.held = "v 1\rv 2\r";
  Link link(device);
  const auto read = read_now(link, kNoWait);
  ASSERT_EQ(read.status, LinkRead::Status::frame);
  EXPECT_EQ(read.frame, "v 1\r");
  EXPECT_EQ(link.buffered_bytes(), "v 2\r") << "the rest stays for the next read";
  EXPECT_EQ(device.reads_started, 0);
  EXPECT_EQ(link.stats().bytes_received, 8u);
}

TEST(LinkNoWait, EndsAtOnceWhenNothingIsThereAndTheNextReadWaits) {
  HeldBytes device;
  Link link(device);
  const auto nothing = read_now(link, kNoWait);
  EXPECT_EQ(nothing.status, LinkRead::Status::timeout);
  EXPECT_TRUE(nothing.partial.empty());
  EXPECT_EQ(device.reads_started, 0) << "no read was started that could take a later byte";

  device.later = "v 3\r";
  const auto waited = read_now(link, LinkTiming{200ms, 20ms});
  ASSERT_EQ(waited.status, LinkRead::Status::frame);
  EXPECT_EQ(waited.frame, "v 3\r");
  EXPECT_EQ(device.reads_started, 1);
}

TEST(LinkNoWait, AnIncompleteFrameIsAPartialTimeoutAndIsTraced) {
  HeldBytes device;
  device.held = "v 4";
  Link link(device);
  std::string traced;
  link.set_tap([&](bool tx, std::string_view bytes) {
    if (!tx) traced += bytes;
  });
  const auto read = read_now(link, kNoWait);
  EXPECT_EQ(read.status, LinkRead::Status::timeout);
  EXPECT_EQ(read.partial, "v 4");
  EXPECT_EQ(traced, "v 4");
  EXPECT_EQ(link.buffered(), 0u);
  EXPECT_EQ(device.reads_started, 0);
}

}  // namespace
}  // namespace fieldgate
