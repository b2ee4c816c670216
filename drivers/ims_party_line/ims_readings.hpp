#pragma once

#include <chrono>
#include <map>
#include <optional>
#include <string>
#include <string_view>

// What the family learns about each unit's reply layout, and what it knows about replies still
// on their way. Pure: time is passed in.
namespace fieldgate::ims {

using Clock = std::chrono::steady_clock;

// Where a query's result comes (README "Reply layouts"): on its own line after the echo's LF
// (the digest's byte examples), or on the echo's line after the echoed command (the manual's
// printed X examples; issue 20).
enum class ResultPlacement { next_line, echo_line };
// When a non-query's echoed LF comes: at once (then an optional CR LF "execution complete"), or
// held until execution, after the CR of the completion ([W]: "the echoed line feed is delayed").
enum class EchoLinefeed { at_once, at_execution };

std::string_view to_string(ResultPlacement placement);
std::string_view to_string(EchoLinefeed linefeed);

// Model options `result_placement: auto|next_line|echo_line` and
// `echo_linefeed: auto|at_once|at_execution`. False for any other value; `out` nullopt for auto
// (detect per unit).
bool parse_result_placement(std::string_view value, std::optional<ResultPlacement>& out);
bool parse_echo_linefeed(std::string_view value, std::optional<EchoLinefeed>& out);

struct ReadingPins {
  std::optional<ResultPlacement> placement;
  std::optional<EchoLinefeed> linefeed;
};

// Per unit: the pinned readings (model options) and the ones seen on the wire. seen_* return a
// line for the log when the reading is news: the first sighting, or a change.
class UnitReadings {
 public:
  void pin(char name, ReadingPins pins) { units_[name].pins = pins; }
  ReadingPins pins(char name) const;

  std::optional<std::string> seen(char name, ResultPlacement placement);
  std::optional<std::string> seen(char name, EchoLinefeed linefeed);
  std::optional<std::string> seen_name_echo(char name, bool with_name);

  std::optional<ResultPlacement> placement(char name) const;
  std::optional<EchoLinefeed> linefeed(char name) const;
  std::optional<bool> echoes_name(char name) const;

 private:
  struct Unit {
    ReadingPins pins;
    std::optional<ResultPlacement> placement;
    std::optional<EchoLinefeed> linefeed;
    std::optional<bool> with_name;
  };
  std::map<char, Unit> units_;
};

// Replies carry no address, so a reply that arrives after its exchange gave up could be taken
// for the answer to the next request (issue 12). This keeps count of the result lines units
// still owe from exchanges that are over, and of units whose echo may still come:
// - a result on its own line is trusted only when nothing else is owed;
// - an echo without the name is trusted only when no other unit, silent since it last
//   answered, may still echo the same command late.
// A debt is written off after `window` without news (README "Late replies").
class LateReplies {
 public:
  // A query's exchange ended before its result line came.
  void owe_result(Clock::time_point now);
  // A late result was consumed where it could not be taken (after a non-query's echo).
  void pay() {
    if (owed_ > 0) --owed_;
  }
  // Bytes that arrived outside an exchange that wanted them: counts the results among them
  // (paid) and the echoes of queries alone (their results will follow).
  void stray(std::string_view bytes, Clock::time_point now);
  int owed() const { return owed_; }
  // Writes off debts older than `window`; returns a log line if it did.
  std::optional<std::string> expire(Clock::time_point now, Clock::duration window);

  // `name` was answering and went silent on `command`: its echo may still come.
  void silent(char name, std::string command, Clock::time_point now);
  // True if an echo of `command` without a name, expected from `name`, could be that late echo.
  bool suspicious(char name, std::string_view command, Clock::time_point now,
                  Clock::duration window) const;

 private:
  int owed_ = 0;
  Clock::time_point since_{};
  std::map<char, std::pair<std::string, Clock::time_point>> silent_;
};

}  // namespace fieldgate::ims
