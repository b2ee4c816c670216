// A C142 that ends its `@0P` reply with a CR sent a little after the digits (issue 26, item 3):
// the reply is complete only once every reading's trailing bytes have arrived or the byte gap
// has passed, so the CR is never read as the next request's answer.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <map>
#include <string>

#include "drivers/techno_c/techno_family.hpp"
#include "fake_line.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

class TechnoLateCr : public ::testing::Test {
 protected:
  void SetUp() override {
    transport_.keep_order();
    transport_.set_far_end([this](std::string_view bytes) { hear(bytes); });
    std::string error;
    Model model;
    model.family = "techno-c";
    node_ = *family_.parse_address("0", error);
    family_.configure_node(node_, model);
    test::run(io_, family_.on_link_open(link_, timing_));
  }

  // A scripted controller: P answers the next position in ack mode, its CR comes 5 ms later.
  void hear(std::string_view bytes) {
    pending_.append(bytes);
    for (auto end = pending_.find('\r'); end != std::string::npos; end = pending_.find('\r')) {
      const std::string line = pending_.substr(0, end);
      pending_.erase(0, end + 1);
      if (line.ends_with("P")) {
        transport_.deliver(fmt::format("0{:06X}000000000000", x_++));
        transport_.deliver("\r", 5ms);
      } else {
        transport_.deliver("0");
      }
    }
  }

  Reply poll() {
    return test::run(
        io_,
        family_.transact(link_, node_, Request{"P", Request::Expect::values, NumberFormat::decimal},
                         timing_));
  }

  asio::io_context io_;
  test::FakeLine transport_{io_, "techno-late-cr", 0};
  Link link_{transport_};
  TechnoFamily family_;
  NodeAddress node_;
  // A byte gap far longer than the CR's delay, so that the reading does not depend on load.
  LinkTiming timing_{1000ms, 200ms};
  std::string pending_;
  int x_ = 1;
};

TEST_F(TechnoLateCr, TheCrAfterAPositionReplyIsNotTheNextAnswer) {
  for (int expected = 1; expected <= 3; ++expected) {
    const Reply reply = poll();
    ASSERT_EQ(reply.status, Reply::Status::ok) << reply.text;
    ASSERT_FALSE(reply.values.empty());
    EXPECT_EQ(reply.values[0], expected);
  }
}

}  // namespace
}  // namespace fieldgate
