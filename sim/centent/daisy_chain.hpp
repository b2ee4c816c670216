#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sim/centent/cn0170_unit.hpp"
#include "sim/common/line_device_loop.hpp"

namespace fieldgate::sim::centent {

struct ChainOptions {
  std::vector<int> units{0};  // unit numbers in physical order (duplicates allowed)
  UnitSettings unit;
  bool power_up = false;        // start as after power-on: every unit waits for its auto-baud CR
  bool strict_autobaud = true;  // a first character other than CR fails the auto-baud (p.1)
  bool select_self_after_reset = true;  // after power-up a unit is selected (as one unit is)
  bool kill_acts_upstream = false;      // a K passing unselected units stops them too
  bool prefix_unit_messages = false;    // [Un] and U<n> carry the unit prefix as well
  std::string prefix_separator;         // between the unit digit and the message: "", " ", ":"
  std::string terminator = "\r";
  std::chrono::microseconds hop_delay{0};  // store-and-forward latency per unit, each way
};

// A daisy chain of CN0170s behind one host port (manual p.13–15): unit commands travel the
// whole chain, other data is trapped by the first unit whose number is selected and passes
// every other unit unaltered; replies are prefixed with the sender's unit number except for 0.
class DaisyChain {
 public:
  DaisyChain(ChainOptions options, SimTime now);

  // A host line ends at CR or LF (`;` separates instructions inside a line).
  static std::size_t frame(std::string_view pending);
  DeviceReply handle(std::string_view line, SimTime now);

  // Family verbs of the control channel (control_help()); nullopt for other verbs.
  std::optional<std::string> control(std::string_view verb, std::span<const std::string> arguments,
                                     SimTime now);
  static std::string control_help();

  struct Stats {
    std::uint64_t lines = 0;       // host lines, blank ones included
    std::uint64_t selections = 0;  // .Un lines
    std::array<std::uint64_t, 10> selections_of{};
    std::uint64_t passed_through = 0;  // lines that left the last unit's Port B
    std::uint64_t lost = 0;            // lines that met an unpowered or un-bauded unit
  };
  const Stats& stats() const { return stats_; }
  std::size_t size() const { return nodes_.size(); }
  Cn0170Unit& unit_at(std::size_t position) { return *nodes_.at(position).unit; }
  // The unit with this number nearest the host, or nullptr.
  Cn0170Unit* find(int number);
  // Lines the unit at `position` trapped.
  std::uint64_t lines_trapped(std::size_t position) const { return nodes_.at(position).lines; }

 private:
  enum class Baud { locked, waiting, failed };
  struct Node {
    std::unique_ptr<Cn0170Unit> unit;
    bool powered = true;
    Baud baud = Baud::locked;
    int selected = -1;  // the number this unit last saw selected
    std::uint64_t lines = 0;
  };
  enum class Pass { on, stop };

  std::string message(const Node& node, std::string_view text, bool unit_message) const;
  void advance(SimTime now);
  Pass unit_command(Node& node, std::string& content, std::string& replies);
  void trap(std::size_t position, const std::string& content, SimTime now, std::string& replies);
  void reset(Node& node, SimTime now);
  Node* resolve(std::string_view address);

  ChainOptions options_;
  std::vector<Node> nodes_;
  std::string outbox_;       // unsolicited lines, sent ahead of the next reply
  int drop_last_lines_ = 0;  // replies of two or more lines still to lose their last line
  Stats stats_;
};

// "0,1,2" -> {0, 1, 2} for the CLI; throws std::invalid_argument.
std::vector<int> parse_unit_list(std::string_view text);

}  // namespace fieldgate::sim::centent
