#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/centent_cn0170/cn0170_codec.hpp"
#include "drivers/protocol_family.hpp"

namespace fieldgate::cn0170 {

// Chain-level settings, from the models' `options:` (README "Options").
struct Options {
  enum class Overflow { warning, rts, leave };
  enum class KillTarget { first_unit, every_unit };
  // Follow every command with M? and wait for the unit's mode reply: the CN0170 acknowledges
  // nothing, so this is how a rejection ("…" ?) or a missing unit is noticed before a Modbus
  // write is answered.
  bool confirm_commands = true;
  Overflow overflow = Overflow::warning;
  // Empty: M1\- (warning) or M1\+ (rts), retried as M1- / M1+ if the unit rejects it (§9 #11).
  std::string overflow_command;
  // Every transmission starts with a CR, so a unit that reset since the last one auto-bauds on
  // it instead of on the next command's first character (§1, §7.1).
  bool leading_cr = true;
  bool autobaud_cr = true;     // lone CR when the link opens
  bool discover_chain = true;  // .U? when the link opens
  KillTarget kill_target = KillTarget::first_unit;
  // Select the unit again before every command even when it is believed selected: a unit that
  // reset selects itself and would trap a command meant for another unit, and a command (unlike
  // a query) has no prefixed reply that would expose the wrong recipient before it runs.
  bool reselect_for_commands = true;
  // Refuse motor and I/O traffic to a unit in Program Mode (M2), where it would be stored.
  bool guard_program_mode = true;
  // Refuse an absolute move whose target and the axis's last polled position lie on different
  // sides of 0 in the signed view: the manual's positions are "positive only" (§9 #20), so a
  // unit comparing them unsigned would run the long way round instead of crossing 0.
  bool guard_position_sign = true;
};

// The options a CN0170 model may set, and a model's options read through them; unknown keys,
// bad values and contradictions are errors at the option's file:line:col.
const ModelOptionSpecs& option_specs();
Options parse_options(const Model& model, Diagnostics& diagnostics);

// Family-defined device error codes (the CN0170 itself has none).
inline constexpr int64_t kRejected = 1;         // the unit answered "…" ?
inline constexpr int64_t kQueueFull = 2;        // Q* in force: instructions would be lost
inline constexpr int64_t kProgramMode = 3;      // unit in M2: would be stored, not run
inline constexpr int64_t kInvalidValue = 4;     // refused by the family before sending
inline constexpr int64_t kStoredInProgram = 5;  // confirmation showed M2: command was stored
// Unit in Operate Mode (M3): the host's instructions may be discarded (or left to its program),
// so nothing is sent, and a confirmation showing M3 confirms nothing.
inline constexpr int64_t kOperateMode = 6;

// The gateway-local read "@counters" (README "Counters"): values in this order.
inline constexpr std::string_view kCountersRequest = "@counters";
enum CounterField {
  kResets,
  kRejects,
  kOverflowWarnings,
  kQueueFullNow,
  kXMoveDone,
  kYMoveDone,
  kXMaxVelocity,
  kYMaxVelocity,
  kUnsolicited,
  kSelections,
  kChainPosition,
  kMode,
  kCounterFields
};

struct UnitCounters {
  uint64_t resets = 0;              // unsolicited U<n>
  uint64_t rejects = 0;             // "…" ?
  uint64_t overflow_warnings = 0;   // Q*
  uint64_t x_done = 0, y_done = 0;  // XP / YP position triggers
  uint64_t x_vmax = 0, y_vmax = 0;  // XV / YV velocity triggers
  uint64_t unsolicited = 0;         // every line from the unit that answered no request
  uint64_t selections = 0;          // .Un sent for it
};

struct UnitState {
  bool configured = false;
  int mode = 0;                   // last M? answer, 0 unknown
  bool set_up = false;            // overflow mode applied since the link opened or the unit reset
  bool queue_full = false;        // Q* seen and no *Q yet
  bool answering = false;         // the last exchange with it got its reply
  bool reset_unreported = false;  // a U<n> came that no reply of this unit has carried yet
  UnitCounters counters;
};

struct LogEvent {
  int level;  // syslog priority: 3 error, 4 warning, 5 notice, 6 info
  std::string text;
};

// What the gateway knows about one daisy chain: the sticky selection, per-unit state and the
// physical order from .U?. One per bus (the family object owns it).
struct Chain {
  std::optional<int> selected;  // unset = uncertain: the next exchange selects explicitly
  std::array<UnitState, kMaxUnit + 1> units;
  std::vector<int> order;  // unit numbers in physical order (duplicates kept)
  bool order_known = false;
  bool drain_before_next = false;  // after a timeout: late replies must not meet the next request
  uint64_t selections = 0;
  uint64_t stray_lines = 0;  // replies nobody waits for any more
  std::vector<LogEvent> events;
  // Replies units still owe from exchanges that gave up (issue 12), by reply key in order. A
  // unit answers in order, so its next replies with these keys are those late ones, never the
  // answer to a new request. Written off after a window without news (README "Late replies").
  std::array<std::deque<std::string>, kMaxUnit + 1> owed;
  std::array<std::chrono::steady_clock::time_point, kMaxUnit + 1> owed_since{};
  uint64_t late_replies = 0;  // skipped as late answers
  // Last polled position register of each unit's X and Y (raw), unknown after a reset.
  std::array<std::array<std::optional<uint32_t>, 2>, kMaxUnit + 1> positions{};

  void forget_selection() { selected.reset(); }
  void owe(int unit, const std::vector<std::string>& keys,
           std::chrono::steady_clock::time_point now);
  // A reply from `unit` with `key` that pays a debt: true if it was owed (and is now paid).
  bool pay(int unit, const std::string& key);
  void expire_owed(std::chrono::steady_clock::time_point now,
                   std::chrono::steady_clock::duration window);
  void link_opened();
  // 1-based place in the chain, 0 when unknown or absent.
  int chain_position(int unit) const;
  // A message no exchange asked for: counts it and applies what it means (a reset forgets the
  // selection, Q* blocks instructions, …).
  void absorb(const Message& m);
  void log(int level, std::string text) { events.push_back({level, std::move(text)}); }
};

// The bytes of one exchange and the replies it waits for.
struct Plan {
  std::string bytes;
  std::vector<Query> expected;    // in order: the request's queries, then the confirmation M?
  bool read = false;              // values wanted
  bool confirmation = false;      // the last expected reply is our M?
  bool program_mode_ok = false;   // a mode change (M1/M3): a confirmation showing M2 is fine
  std::optional<Reply> refused;   // the family refuses without sending anything
  std::optional<int> reply_unit;  // whose replies are awaited, when not the request's unit
  bool leading_cr = false;        // a unit that reset auto-bauds on it, so the rest gets through
  bool selects = false;           // .Un is part of the bytes
};

// Builds the exchange for `request` to `unit` and updates the selection it implies.
Plan plan_request(Chain& chain, const Options& options, int unit, const Request& request);
// Bus-wide kill (K relayed down the chain from the first unit, §2 "Kill").
Plan plan_kill(Chain& chain, const Options& options, int unit, const std::vector<int>& configured);

// One exchange with one unit, fed line by line: the I/O-free decision part of transact().
class Exchange {
 public:
  Exchange(Chain& chain, int unit, Plan plan, std::string what);
  // True once the exchange is over; reply() is then final.
  bool on_line(std::string_view line);
  // The line reader ended: nothing more within the reply timeout (`partial` = an unterminated
  // line), a line longer than any reply, or too many unrelated lines.
  Reply on_timeout(std::string_view partial);
  Reply on_overflow(std::string_view partial);
  Reply on_too_many_lines();
  Reply on_link_error(std::string text);
  bool finished() const { return finished_; }
  int unit() const { return unit_; }
  // Reply keys still on their way when the exchange gave up (for Chain::owe).
  const std::vector<std::string>& owes() const { return owes_; }
  // Since when the debts this exchange paid had been open: a new debt it leaves keeps that age.
  // An exchange that takes its own reply for a late one (the late one was lost or cut) would
  // otherwise owe it again as new, every poll, and never reach the write-off.
  std::optional<std::chrono::steady_clock::time_point> paid_debt_since() const {
    return paid_debt_since_;
  }
  const Reply& reply() const { return reply_; }

 private:
  bool finish(Reply::Status status, std::string text, int64_t code = 0);
  bool finish_ok();
  void lost();

  Chain& chain_;
  int unit_;
  Plan plan_;
  std::string what_;
  std::size_t next_ = 0;
  std::vector<int64_t> values_;
  int64_t motion_ = 0;
  bool saw_position_ = false;
  std::optional<int> reset_seen_;
  bool was_answering_ = false;
  std::vector<std::string> owes_;
  std::optional<std::chrono::steady_clock::time_point> paid_debt_since_;
  void owe_rest(std::size_t from);
  int confirmed_mode_ = 0;
  Reply reply_;
  bool finished_ = false;
};

// Values of the local read "@counters" for `unit`.
std::vector<int64_t> counters_of(const Chain& chain, int unit);

}  // namespace fieldgate::cn0170
