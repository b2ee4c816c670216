// prove_alignment: the known answers prove the line in step only when no stale reply can stand in
// for them, and a reply owed to a request the device never heard costs no extra wait.
#include <gtest/gtest.h>

#include <boost/asio/io_context.hpp>

#include "drivers/alignment_proof.hpp"
#include "fake_line.hpp"

namespace fieldgate {
namespace {

using namespace std::chrono_literals;

std::size_t line(std::string_view b) {
  const auto p = b.find('\r');
  return p == std::string_view::npos ? 0 : p + 1;
}

// Two steps with different known answers: "A" -> "a", "B" -> "b".
AlignmentProof two_step_proof() {
  AlignmentProof proof;
  proof.name = "A -> a, B -> b";
  proof.steps.push_back({"A\r", line, [](std::string_view f) { return f == "a\r"; }, "'a'"});
  proof.steps.push_back({"B\r", line, [](std::string_view f) { return f == "b\r"; }, "'b'"});
  return proof;
}

// A device that answers every request at once, in order, after whatever the line still owes.
class InOrderDevice {
 public:
  explicit InOrderDevice(asio::io_context& io) : line_(io, "in-order device", 0) {
    line_.keep_order();
    line_.set_far_end([this](std::string_view written) {
      if (written == "A\r") line_.deliver("a\r");
      if (written == "B\r") line_.deliver("b\r");
    });
  }
  // Stale replies already on their way before the proof starts.
  void stale(std::string bytes) { line_.deliver(std::move(bytes), 1ms); }
  test::FakeLine& line() { return line_; }

 private:
  test::FakeLine line_;
};

class AlignmentProofTest : public ::testing::Test {
 protected:
  AlignmentResult prove(AlignmentDebt& debt, int attempts = 3) {
    return test::run(io_, prove_alignment(link_, proof_, timing_, guard_, attempts, debt));
  }

  asio::io_context io_;
  InOrderDevice device_{io_};
  Link link_{device_.line()};
  AlignmentProof proof_ = two_step_proof();
  LinkTiming timing_{50ms, 5ms, 0us};
  std::chrono::microseconds guard_{20ms};
};

TEST_F(AlignmentProofTest, AReplyOwedToARequestNeverHeardIsTakenAsLostInOneAttempt) {
  AlignmentDebt debt;
  debt.add();  // an earlier request got no reply, and none will come
  const auto result = prove(debt);
  EXPECT_TRUE(result.proved) << result.why;
  EXPECT_EQ(result.attempts, 1);
  EXPECT_EQ(result.lost, 1u);
  EXPECT_TRUE(result.strays.empty());
  EXPECT_EQ(debt.owed, 0u);
  EXPECT_EQ(device_.line().writes().size(), 2u);
}

TEST_F(AlignmentProofTest, AStaleCopyOfTheFirstAnswerFailsTheAttemptThatItWouldPass) {
  AlignmentDebt debt;
  debt.add();
  device_.stale("a\r");  // a late answer to an earlier proof's first step
  const auto result = prove(debt);
  ASSERT_TRUE(result.proved) << result.why;
  // The first attempt read the stale "a" as its first answer, then its own "a" where "b" was
  // due: it failed, and the second (reversed) attempt proved the line.
  EXPECT_EQ(result.attempts, 2);
  EXPECT_EQ(link_.buffered(), 0u);
  ASSERT_GE(device_.line().writes().size(), 4u);
  EXPECT_EQ(device_.line().writes()[2], "B\r");
}

TEST_F(AlignmentProofTest, TwoStaleRepliesThatFormThePatternAreReadThroughFirst) {
  AlignmentDebt debt;
  debt.add();
  debt.add();
  device_.stale("a\r");  // an earlier proof's two answers, both late
  device_.stale("b\r");
  const auto result = prove(debt);
  ASSERT_TRUE(result.proved) << result.why;
  EXPECT_EQ(result.attempts, 1);
  // The stale pair matched first; the proof read on until its own answers had come.
  EXPECT_EQ(result.strays.size(), 2u);
  EXPECT_EQ(debt.owed, 0u);
  EXPECT_EQ(link_.buffered(), 0u);
  // Nothing of this attempt is left on the line for the next request.
  const LinkTiming short_wait{10ms, 5ms, 0us};
  const auto next = test::run(io_, link_.read_frame(line, short_wait));
  EXPECT_EQ(next.status, LinkRead::Status::timeout);
  EXPECT_TRUE(next.partial.empty());
}

TEST_F(AlignmentProofTest, NothingOwedProvesInOneAttemptWithoutStrays) {
  AlignmentDebt debt;
  const auto result = prove(debt);
  EXPECT_TRUE(result.proved) << result.why;
  EXPECT_EQ(result.attempts, 1);
  EXPECT_EQ(result.lost, 0u);
  EXPECT_TRUE(result.strays.empty());
}

}  // namespace
}  // namespace fieldgate
