#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace fieldgate::ims {

// Codes of the commands the family refuses before they reach the wire. The manual defines no
// device error codes at all (§7), so these are the gateway's own; they appear in the action
// error register and the diagnostic block's last device error.
enum class Refusal : int64_t {
  output_value = 1,  // A<v> with v not one of 0, 8, …, 56
  axis_moving = 2,   // an index or set-origin while the axis moves (§6, §8.3)
  eeprom_rate = 3,   // S again within the save interval (§5 EEPROM-wear rules)
  not_global = 4,    // an urgent command that is not ESC, ^C or @
  invalid_line = 5,  // empty, or CR, LF, ESC or ^C inside an addressed command
};

struct RefusalReply {
  Refusal code;
  std::string text;
};

// What the family knows about the units on its chain from the commands it sent and the status
// replies it read: the party line has no readback of V, K, … (§4), so this is a shadow.
//
// It decides
// - pacing: above 10,000 steps/s a unit's serial handling slows and its UART can overrun (§1
//   "Latency", p.14); every unit listens to the host's line, so one fast axis paces the chain;
// - the motion guard: a second index queues behind the running one and the unit answers nothing
//   until it starts (§6, §8.3), so an index or `O` while the axis moves is refused;
// - the EEPROM guard: `S` at most once per save interval per unit (§5, §8.10).
//
// Pure: time is passed in; transact() calls it around each exchange.
class ChainShadow {
 public:
  using Clock = std::chrono::steady_clock;

  static constexpr double kFastStepRate = 10'000.0;  // steps/s, manual p.14
  static constexpr std::chrono::seconds kSaveInterval{60};

  // A unit's thresholds: its model's options pacing_step_rate and save_interval.
  struct Limits {
    double fast_step_rate = kFastStepRate;
    std::chrono::microseconds save_interval = kSaveInterval;
  };
  // The unit's limits from now on (a unit never limited has the defaults).
  void limit(char name, Limits limits) { limits_[name] = limits; }
  const Limits& limits(char name) const;

  // nullopt if `command` may go to `name` now.
  std::optional<RefusalReply> check(char name, std::string_view command,
                                    Clock::time_point now) const;
  // The unit echoed `command` (and, for `^`, answered `result`).
  void acknowledged(char name, std::string_view command, Clock::time_point now,
                    std::optional<int64_t> result = std::nullopt);
  // A global command went to every unit (ESC, ^C, @, or `*<command>`).
  void global(std::string_view command, Clock::time_point now);

  // True while any unit may be stepping faster than its fast_step_rate.
  bool fast() const;
  // The step rate the shadow assumes for a unit (0 when it is known to stand still).
  double step_rate(char name) const;
  bool moving(char name) const;
  // The unit's motion is a jog (M with a speed, or its ramp after M0) that `^` has not yet shown
  // ended: an index for it is taken as "abort the jog, then index" (ImsPartyLineFamily).
  bool jogging(char name) const;

 private:
  struct Unit {
    std::optional<double> slew;  // last V sent; unknown after a reset
    double step_rate = 0;        // of the motion last started, until `^` says idle
    bool moving = false;         // a motion command was acknowledged and `^` has not shown idle
    bool jogging = false;        // that motion is a jog (M)
    bool status_seen = false;    // the model polls `^`, so `moving` gets cleared
    std::optional<Clock::time_point> last_save;
  };

  void motion_started(Unit& unit, std::string_view command);

  std::map<char, Unit> units_;
  std::map<char, Limits> limits_;
};

}  // namespace fieldgate::ims
