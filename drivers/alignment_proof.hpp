#pragma once

#include <boost/asio/awaitable.hpp>

#include <algorithm>
#include <chrono>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/link.hpp"

namespace fieldgate {

// Untagged replies carry nothing that ties them to a request, and a quiet line is no proof that
// no late reply is still coming (a device may be silent past the timeout, then answer its
// backlog). After any timeout, garbled or partial reply or stray bytes, a stream bus trusts a
// reply again only once an exchange has proved that the line is in step: every step's answer is
// known in advance, and each differs from the step before it, so a stray reply taken for a
// step's answer makes the next step read the real one and fail. Every reply that arrives in
// between is drained, counted and logged. Each untagged family names its own proof
// (ProtocolFamily::alignment_proof).
struct AlignmentStep {
  std::string request;     // bytes sent, framing included
  FrameSplitter splitter;  // frames this step's whole reply (echo and prompt included)
  // True when a frame is exactly this step's known answer.
  std::function<bool(std::string_view frame)> matches;
  std::string expected;  // what the answer is, for logs
  // Non-zero: the request goes one character at a time, this far apart (a unit whose UART
  // overruns on back-to-back characters, as an IMS indexer stepping fast).
  std::chrono::microseconds char_gap{0};
};

struct AlignmentProof {
  std::string name;  // the exchange, for logs ("g f0x32 -> e 15, g r0x90 -> v <baud>")
  // At least two steps, each answer different from the previous step's.
  std::vector<AlignmentStep> steps;
  // Every other attempt runs the steps in reverse order, so that the answers of a failed
  // attempt that arrive late (the same known answers) cannot pass the next attempt in step:
  // with steps A, B the answers come as A B | B A | A B, and only an attempt's own pair reads
  // as its pattern. False where the order matters (a write, then its read-back).
  bool reversible = true;
};

// What the line may still owe, kept by the bus between proofs: replies to requests that got none
// (capped: a device that was away owes nothing for what it never heard, and one that was busy
// owes a few), and whether the last attempt got exactly its answers while replies stayed owed.
struct AlignmentDebt {
  static constexpr std::size_t kMaxOwed = 4;
  std::size_t owed = 0;
  bool clean_but_owing = false;
  void add() { owed = std::min(owed + 1, kMaxOwed); }
  void clear() { *this = AlignmentDebt{}; }
  // Whole frames among bytes drained while waiting for quiet are owed replies arriving: each
  // pays one. Returns how many did.
  std::size_t settle(std::string_view drained, const FrameSplitter& splitter);
};

// How an attempt that did not prove the line ended.
enum class AttemptEnd {
  no_reply,     // a step's request got nothing at all within the timeout
  wrong_reply,  // something came that was not the known answer (stray, garbled, partial, extra)
  not_sent,     // the request could not be written
  // Every answer came in order and nothing else, but replies are still owed: not a failure of
  // the device (see prove_alignment).
  clean_but_owing,
};

struct FailedAttempt {
  AttemptEnd end;
  std::string why;
};

struct AlignmentResult {
  bool proved = false;
  int attempts = 0;
  std::vector<std::string> strays;      // replies (or partial bytes) read and thrown away
  std::size_t lost = 0;                 // owed replies given up as lost (see prove_alignment)
  std::vector<FailedAttempt> failures;  // every attempt that did not prove the line, in order
  bool never_quiet = false;  // after a failed attempt the line kept talking: the proof gave up
  std::string why;           // what the last failed attempt saw
};

// Runs the proof up to `attempts` times. The first step's request may be answered after stray
// replies (the backlog drains ahead of it: each is counted); every later step must be answered
// by its own reply, and nothing may follow the last. A failed attempt waits for the line to go
// quiet (Link::resync with `guard`) before the next.
// `owed` counts replies the line still owes (the caller adds the requests of a failed exchange
// that got no reply; the proof adds its own requests and takes off every frame read). A device
// answers in order, so the known answers prove the line in step only when nothing is owed after
// them: otherwise they may be stale answers to an earlier attempt's identical requests, and the
// owed ones are read first. Owed replies that never come while two attempts in a row get exactly
// their answers were lost (a request the device never heard), and are forgiven.
asio::awaitable<AlignmentResult> prove_alignment(Link& link, const AlignmentProof& proof,
                                                 const LinkTiming& timing,
                                                 std::chrono::microseconds guard, int attempts,
                                                 AlignmentDebt& debt);
// The same with nothing owed before the proof (tests, tools).
inline asio::awaitable<AlignmentResult> prove_alignment(Link& link, const AlignmentProof& proof,
                                                        const LinkTiming& timing,
                                                        std::chrono::microseconds guard,
                                                        int attempts) {
  AlignmentDebt debt;
  co_return co_await prove_alignment(link, proof, timing, guard, attempts, debt);
}

}  // namespace fieldgate
