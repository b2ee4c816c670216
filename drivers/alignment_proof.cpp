#include "drivers/alignment_proof.hpp"

#include <fmt/format.h>

#include <optional>

#include "drivers/printable_bytes.hpp"

namespace fieldgate {

namespace {

// The first step drains whatever arrives ahead of its answer, but not forever: a line that keeps
// producing frames that are not the answer is not coming into step.
constexpr int kMaxStraysPerStep = 16;

// An attempt's end: proved (nothing), or how it did not.
using Outcome = std::optional<AttemptEnd>;
constexpr Outcome kProved = std::nullopt;

class Attempt {
 public:
  Attempt(Link& link, const AlignmentProof& proof, bool reversed, const LinkTiming& timing,
          AlignmentResult& result, AlignmentDebt& debt)
      : link_(link),
        proof_(proof),
        reversed_(reversed),
        timing_(timing),
        result_(result),
        debt_(debt),
        owed_before_(debt.owed) {}

  asio::awaitable<Outcome> run() {
    const std::size_t count = proof_.steps.size();
    for (std::size_t i = 0; i < count; ++i) {
      const auto& step = this->step(i);
      if (auto ec = co_await send(step)) {
        why_ = "cannot send: " + ec.message();
        co_return AttemptEnd::not_sent;
      }
      debt_.add();
      for (int read_count = 0;; ++read_count) {
        auto frame = co_await read(step);
        if (!frame) co_return read_end_;
        if (step.matches(*frame)) break;
        stray(std::move(*frame));
        // Later steps follow an answered step: anything but their own answer means the line is
        // still out of step (or a stray equalled the previous answer).
        if (i > 0 || read_count + 1 >= kMaxStraysPerStep) {
          why_ = fmt::format("'{}' to '{}' where {} was expected",
                             printable_bytes(result_.strays.back()), printable_bytes(step.request),
                             step.expected);
          co_return AttemptEnd::wrong_reply;
        }
      }
    }
    // Stale replies fewer than the steps cannot form the pattern: each answer differs from the
    // one before it, so a stale frame taken for one step leaves the next step reading the real
    // answer of the step before. What is still owed then never comes (a device answers in
    // order, and its answers to this attempt have arrived): it was lost.
    if (debt_.owed == 0 || owed_before_ < count) {
      if (link_.buffered() > 0) co_return bytes_followed();
      result_.lost += debt_.owed;
      co_return kProved;
    }
    // Replies are owed: a device answers in order, so if the answers just read were stale ones,
    // this attempt's own follow. Read them; the last `count` frames must be the pattern again.
    const bool clean = strays_ == 0;
    std::vector<std::string> last;
    while (debt_.owed > 0) {
      auto frame = co_await read(this->step(count - 1));
      if (!frame) {
        if (clean && read_end_ == AttemptEnd::no_reply) co_return AttemptEnd::clean_but_owing;
        co_return read_end_;
      }
      last.push_back(*frame);
      stray(std::move(*frame));
    }
    if (last.size() < count) {
      why_ = "too few replies after stale answers";
      co_return AttemptEnd::wrong_reply;
    }
    for (std::size_t i = 0; i < count; ++i)
      if (!this->step(i).matches(last[last.size() - count + i])) {
        why_ = "the replies owed after stale answers were not the proof's";
        co_return AttemptEnd::wrong_reply;
      }
    if (link_.buffered() > 0) co_return bytes_followed();
    co_return kProved;
  }

  const std::string& why() const { return why_; }

 private:
  const AlignmentStep& step(std::size_t i) const {
    return proof_.steps[reversed_ ? proof_.steps.size() - 1 - i : i];
  }
  asio::awaitable<std::error_code> send(const AlignmentStep& step) {
    if (step.char_gap.count() == 0) co_return co_await link_.send(step.request);
    const std::string_view request = step.request;
    for (std::size_t i = 0; i < request.size(); ++i) {
      if (i > 0) co_await link_.pause(step.char_gap);
      if (auto ec = co_await link_.send(request.substr(i, 1))) co_return ec;
    }
    co_return std::error_code{};
  }
  asio::awaitable<std::optional<std::string>> read(const AlignmentStep& step) {
    const auto read = co_await link_.read_frame(step.splitter, timing_);
    if (read.status == LinkRead::Status::frame) {
      ++frames_read_;
      if (debt_.owed > 0) --debt_.owed;
      co_return read.frame;
    }
    if (!read.partial.empty()) stray(read.partial);
    // Silence after more frames than were owed: one of them was this attempt's answer, wrong.
    read_end_ = read.status == LinkRead::Status::timeout && read.partial.empty() &&
                        frames_read_ <= owed_before_
                    ? AttemptEnd::no_reply
                    : AttemptEnd::wrong_reply;
    why_ = fmt::format(
        "{} to '{}' where {} was expected",
        read.status == LinkRead::Status::timeout
            ? (read.partial.empty() ? std::string("no reply")
                                    : "incomplete '" + printable_bytes(read.partial) + "'")
            : std::string("an overlong or failed read"),
        printable_bytes(step.request), step.expected);
    co_return std::nullopt;
  }
  AttemptEnd bytes_followed() {
    why_ = "bytes followed the last answer";
    return AttemptEnd::wrong_reply;
  }
  void stray(std::string bytes) {
    ++strays_;
    result_.strays.push_back(std::move(bytes));
  }

  Link& link_;
  const AlignmentProof& proof_;
  bool reversed_;
  const LinkTiming& timing_;
  AlignmentResult& result_;
  AlignmentDebt& debt_;
  const std::size_t owed_before_;
  std::size_t frames_read_ = 0;
  int strays_ = 0;
  AttemptEnd read_end_ = AttemptEnd::no_reply;  // how the last failed read ended
  std::string why_;
};

}  // namespace

std::size_t AlignmentDebt::settle(std::string_view drained, const FrameSplitter& splitter) {
  std::size_t paid = 0;
  while (!drained.empty() && owed > 0) {
    const std::size_t length = splitter(drained);
    if (length == 0 || length > drained.size()) break;
    --owed;
    ++paid;
    drained.remove_prefix(length);
  }
  return paid;
}

asio::awaitable<AlignmentResult> prove_alignment(Link& link, const AlignmentProof& proof,
                                                 const LinkTiming& timing,
                                                 std::chrono::microseconds guard, int attempts,
                                                 AlignmentDebt& debt) {
  AlignmentResult result;
  while (result.attempts < attempts) {
    ++result.attempts;
    const bool reversed = proof.reversible && result.attempts % 2 == 0;
    Attempt attempt(link, proof, reversed, timing, result, debt);
    const Outcome outcome = co_await attempt.run();
    if (outcome == kProved) {
      debt.clear();
      result.proved = true;
      result.why.clear();
      co_return result;
    }
    result.failures.push_back({*outcome, attempt.why()});
    result.why = attempt.why();
    if (*outcome == AttemptEnd::clean_but_owing) {
      // Twice in a row every answer came in order, nothing else arrived, and what is owed never
      // came: those replies were lost (a request the device never heard), not late.
      if (debt.clean_but_owing) {
        result.lost = debt.owed;
        debt.clear();
        result.proved = true;
        result.why.clear();
        co_return result;
      }
      debt.clean_but_owing = true;
    } else {
      debt.clean_but_owing = false;
    }
    const auto drained = co_await link.resync(guard, 10 * guard);
    if (!drained.drained.empty()) {
      result.strays.push_back(drained.drained);
      debt.settle(drained.drained, proof.steps.front().splitter);
    }
    if (!drained.quiet) {
      result.never_quiet = true;
      result.why += "; the line never went quiet";
      co_return result;
    }
  }
  co_return result;
}

}  // namespace fieldgate
