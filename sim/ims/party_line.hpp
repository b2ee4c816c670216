#pragma once

#include <chrono>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sim/common/line_device_loop.hpp"
#include "sim/ims/indexer.hpp"

namespace fieldgate::sim::ims {

struct PartyLineOptions {
  std::vector<char> names{'A'};
  HomeSwitch home;
  // Whether a unit echoes its own name (the manual does not say, §2).
  bool echo_name = false;
  // CR LF "execution complete" after commands without a numeric result (p.12).
  bool completion = true;
  // A query's result on the echo's line, after the echoed command: the echoed LF is left out
  // and the result (with its own line end) takes its place ("X Y= 0/25 …", p.47; issue 20).
  bool result_on_echo_line = false;
  // The echoed LF of a non-query is held until execution and comes after the CR of the
  // completion ([W] "the echoed line feed is delayed"): "AV2000" … "\r\n".
  bool linefeed_at_execution = false;
  ResultFormat result_format;
  // A unit stepping faster than this (steps/s) drops characters that arrive back to back
  // (manual p.14); 0 turns the overrun off.
  double overrun_above = 10'000;
  // Characters read together came back to back unless at least this much time per character
  // passed since the line's previous read: a host pacing by time (the alignment proof's 5 ms)
  // gets through a simulator that was not scheduled for a while.
  std::chrono::microseconds overrun_spacing{1000};
  std::uint32_t seed = 1;
};

// Several IMS indexers in party-line mode on one RS-422 pair (shared/protocols/ims-indexer.md
// §2): every unit hears every character; the unit whose name starts a line wakes, echoes the
// line character by character and executes it at the LF. ESC, ^C, `@` lines and `*` lines reach
// every unit.
//
// Plugs into LineExchange through frame(), echo() and respond(). Faults from the control channel
// (garbage, truncate) are applied to the echo here, because on a party line the echo is the
// reply; LineExchange applies the rest (silence, delay) as for any family.
class PartyLine {
 public:
  // `clock` tells echo() the time (it is called as bytes arrive, without a time of its own);
  // tests pass their injected time.
  PartyLine(PartyLineOptions options, FaultInjection& faults, std::function<SimTime()> clock,
            SimTime now);

  // A request ends at LF; ESC and ^C are requests on their own and cut a line short.
  static std::size_t frame(std::string_view pending);
  // What the units send back while `received` arrives (LineDeviceHooks::echo).
  std::string echo(std::string_view received);
  // Executes a framed request at `now` and returns result lines or completions.
  DeviceReply respond(std::string_view request, SimTime now);

  LineDeviceHooks hooks();

  // Family commands of the control channel; nullopt for other verbs.
  std::optional<std::string> control(std::string_view verb, std::span<const std::string> arguments,
                                     SimTime now);
  static std::string control_help();

  // nullptr if no unit has that name.
  Indexer* unit(char name);
  bool online(char name) const;

 private:
  enum class Target { none, unit, all, soft_stop };
  enum class Fault { none, garbage, truncate, overrun, collision };

  struct Unit {
    Indexer indexer;
    bool online = true;
    bool duplicate = false;  // a second unit with the same name answers too
    int overruns = 0;        // lines it lost to characters arriving back to back
  };

  // The line being received, as the listening units see it.
  struct Line {
    bool started = false;
    std::string text;  // name (or * or @) included
    Target target = Target::none;
    Fault fault = Fault::none;
    bool echoing = false;
    bool hold_linefeed = false;      // W keeps its LF until the wait ends
    bool withheld_linefeed = false;  // the echoed LF comes with the result or at execution
    std::size_t body = 0;            // characters after the name
    SimTime last_read{};             // when the previous read brought characters of this line
  };

  void start_line(char first, std::string& out);
  bool back_to_back(std::size_t in_this_read, bool started_in_this_read, SimTime now) const;
  char disturbed(char c);
  std::vector<Unit*> units_named(char name);
  std::vector<Unit*> online_units();
  std::string collide(std::string_view bytes);
  std::optional<char> name_argument(std::span<const std::string> arguments, std::string& error);

  PartyLineOptions options_;
  FaultInjection& faults_;
  std::function<SimTime()> clock_;
  std::map<char, Unit> units_;
  Line line_;
  std::deque<Line> heard_;  // complete lines, in order, waiting for respond()
  std::mt19937 random_;
};

// "A,B,C" -> {'A','B','C'}; throws std::invalid_argument for an invalid or repeated name.
std::vector<char> parse_names(std::string_view text);

}  // namespace fieldgate::sim::ims
