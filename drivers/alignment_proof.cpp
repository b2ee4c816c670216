#include "drivers/alignment_proof.hpp"

#include <fmt/format.h>

#include "drivers/printable_bytes.hpp"

namespace fieldgate {

namespace {

// The first step drains whatever arrives ahead of its answer, but not forever: a line that keeps
// producing frames that are not the answer is not coming into step.
constexpr int kMaxStraysPerStep = 16;

// One attempt: true when every step got its known answer, in order, and nothing followed.
asio::awaitable<bool> attempt_once(Link& link, const AlignmentProof& proof,
                                   const LinkTiming& timing, AlignmentResult& result) {
  for (std::size_t i = 0; i < proof.steps.size(); ++i) {
    const auto& step = proof.steps[i];
    if (auto ec = co_await link.send(step.request)) {
      result.why = "cannot send: " + ec.message();
      co_return false;
    }
    for (int read_count = 0;; ++read_count) {
      const auto read = co_await link.read_frame(step.splitter, timing);
      if (read.status != LinkRead::Status::frame) {
        if (!read.partial.empty()) result.strays.push_back(read.partial);
        result.why = fmt::format(
            "{} to '{}' where {} was expected",
            read.status == LinkRead::Status::timeout
                ? (read.partial.empty() ? std::string("no reply")
                                        : "incomplete '" + printable_bytes(read.partial) + "'")
                : std::string("an overlong or failed read"),
            printable_bytes(step.request), step.expected);
        co_return false;
      }
      if (step.matches(read.frame)) break;
      result.strays.push_back(read.frame);
      // Later steps follow an answered step: anything but their own answer means the line is
      // still out of step (or a stray equalled the previous answer).
      if (i > 0 || read_count + 1 >= kMaxStraysPerStep) {
        result.why = fmt::format("'{}' to '{}' where {} was expected", printable_bytes(read.frame),
                                 printable_bytes(step.request), step.expected);
        co_return false;
      }
    }
  }
  if (link.buffered() > 0) {
    result.why = "bytes followed the last answer";
    co_return false;
  }
  co_return true;
}

}  // namespace

asio::awaitable<AlignmentResult> prove_alignment(Link& link, const AlignmentProof& proof,
                                                 const LinkTiming& timing,
                                                 std::chrono::microseconds guard, int attempts) {
  AlignmentResult result;
  while (result.attempts < attempts) {
    ++result.attempts;
    if (co_await attempt_once(link, proof, timing, result)) {
      result.proved = true;
      result.why.clear();
      co_return result;
    }
    const auto drained = co_await link.resync(guard, 10 * guard);
    if (!drained.drained.empty()) result.strays.push_back(drained.drained);
    if (!drained.quiet) {
      result.why += "; the line never went quiet";
      co_return result;
    }
  }
  co_return result;
}

}  // namespace fieldgate
