#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "drivers/ims_party_line/ims_readings.hpp"
#include "drivers/protocol_family.hpp"

namespace fieldgate::ims {

// Stray blank lines (a late completion of an earlier command) before a line are skipped, a few
// at most.
inline constexpr int kMaxBlankLines = 3;

// A query, or a read: the echo is followed by a result.
bool expects_result(const Request& request);

// What the family remembers of one unit between exchanges.
struct UnitTrack {
  bool answering = false;      // the unit's echo came on its last exchange
  int single_mode_echoes = 0;  // exchanges in a row whose echo looked like Single mode's
};

struct LogLine {
  int level;  // syslog priority: 4 warning, 5 notice
  std::string text;
};

// One exchange with one unit, fed what the line reader got: the I/O-free decision part of
// ImsPartyLineFamily::transact(). It keeps the units' readings and the replies still owed up to
// date, takes the time from its caller, and says what to read next. Every failure ends through
// one path (fail), which also notes a unit that was answering and went silent.
class Exchange {
 public:
  // What the caller reads next: the echo line, what follows an echo whose LF came at once (the
  // CR LF of "execution complete", within a byte time), the result line; or nothing (reply()).
  enum class Next { echo, completion, result, done };

  Exchange(const NodeAddress& node, const Request& request, UnitReadings& readings,
           LateReplies& late, UnitTrack& unit, Clock::duration late_window);

  // The line did not go out whole: a write failed, or a paced send's echo stopped (`echoed` is
  // what came back of the line so far).
  Next on_send_failure(Reply failure, std::string_view echoed, Clock::time_point now);
  Next on_echo(std::string_view line, Clock::time_point now);
  // No echo line within the timeout: `partial` is what came of it.
  Next on_echo_failure(Reply failure, std::string_view partial, Clock::time_point now);
  // `bytes`: what came after the echo within a byte time (empty if nothing did).
  Next on_completion(std::string_view bytes, Clock::time_point now);
  Next on_result(std::string_view line, Clock::time_point now);
  Next on_result_failure(Reply failure, Clock::time_point now);
  Next on_link_down(std::string text);

  Next next() const { return next_; }
  // Final once next() is done. A garbled reply leaves the line to be drained before the next
  // exchange (the rest of it may still be coming).
  const Reply& reply() const { return reply_; }
  std::vector<LogLine> take_log() { return std::exchange(log_, {}); }

 private:
  Next finish(Reply reply);
  Next fail(Reply failure, Clock::time_point now);
  void log(int level, std::optional<std::string> text);
  // One Single mode echo may be a cut line; two in a row is what the unit does, and the reply
  // says so.
  Reply single_mode_reply(Reply failure, std::string_view partial);

  const NodeAddress& node_;
  const Request& request_;
  char name_;
  bool query_;
  ReadingPins pins_;
  UnitReadings& readings_;
  LateReplies& late_;
  UnitTrack& unit_;
  Clock::duration late_window_;
  Next next_ = Next::echo;
  Reply reply_;
  std::vector<LogLine> log_;
};

}  // namespace fieldgate::ims

namespace fieldgate {

// What a result line means for a query.
Reply interpret_ims_result(const NodeAddress& node, const Request& request, std::string_view line);
// Everything a unit sent back after the request, as if it all arrived before the deadline:
// stray blank lines, the echo, and the result line or completion. An ims::Exchange with nothing
// pinned and nothing owed, fed the transcript.
Reply interpret_ims_reply(const NodeAddress& node, const Request& request,
                          std::string_view received);

}  // namespace fieldgate
