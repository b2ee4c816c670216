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
      if (deaf_) return;
      if (garble_next_ > 0) {
        --garble_next_;
        line_.deliver("#\r");
        return;
      }
      if (written == "A\r") line_.deliver("a\r");
      if (written == "B\r") line_.deliver("b\r");
    });
  }
  void garble_next(int requests) { garble_next_ = requests; }
  void deaf() { deaf_ = true; }
  // Stale replies already on their way before the proof starts.
  void stale(std::string bytes) { line_.deliver(std::move(bytes), 1ms); }
  test::FakeLine& line() { return line_; }

 private:
  test::FakeLine line_;
  int garble_next_ = 0;
  bool deaf_ = false;
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

TEST_F(AlignmentProofTest, AGarbledAnswerEndsItsAttemptAsAWrongReplyThoughSilenceFollowsIt) {
  AlignmentDebt debt;
  device_.garble_next(1);
  const auto result = prove(debt);
  ASSERT_TRUE(result.proved) << result.why;
  EXPECT_EQ(result.attempts, 2);
  // The garbled frame was this attempt's own answer (nothing was owed): the device's failure
  // to answer as it must, counted as such by the bus, not as silence.
  ASSERT_EQ(result.failures.size(), 1u);
  EXPECT_EQ(result.failures[0].end, AttemptEnd::wrong_reply);
}

TEST_F(AlignmentProofTest, AnOwedReplyAndThenSilenceIsNoReplyFromTheDevice) {
  AlignmentDebt debt;
  debt.add();
  device_.stale("z\r");  // the late reply the line owed
  device_.deaf();
  const auto result = prove(debt, 1);
  EXPECT_FALSE(result.proved);
  ASSERT_EQ(result.failures.size(), 1u);
  EXPECT_EQ(result.failures[0].end, AttemptEnd::no_reply) << result.failures[0].why;
  EXPECT_FALSE(result.never_quiet);
}

TEST_F(AlignmentProofTest, ASilentDeviceFailsEveryAttemptAsNoReply) {
  AlignmentDebt debt;
  device_.deaf();
  const auto result = prove(debt, 2);
  EXPECT_FALSE(result.proved);
  EXPECT_EQ(result.attempts, 2);
  ASSERT_EQ(result.failures.size(), 2u);
  for (const auto& failure : result.failures) EXPECT_EQ(failure.end, AttemptEnd::no_reply);
  EXPECT_EQ(result.why, result.failures.back().why);
}

TEST(AlignmentDebtTest, WholeDrainedFramesPayWhatIsOwedAndNoMore) {
  AlignmentDebt debt;
  debt.add();
  debt.add();
  EXPECT_EQ(debt.settle("a\rb\rc\r", line), 2u);
  EXPECT_EQ(debt.owed, 0u);
  debt.add();
  EXPECT_EQ(debt.settle("partial", line), 0u);  // no whole frame
  EXPECT_EQ(debt.owed, 1u);
}

}  // namespace
}  // namespace fieldgate
