#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace fieldgate::sparkplug {

// A primary host application's STATE message (Sparkplug 3.0, spBv1.0/STATE/<host_id>): the JSON
// object {"online": true|false, "timestamp": <ms since the epoch>}, retained by the broker.
struct HostState {
  bool online = false;
  uint64_t timestamp = 0;
};

// nullopt when the text is not such an object (both members are required).
std::optional<HostState> parse_host_state(std::string_view json);

// Tracks the latest STATE: a message older than the one in force is ignored (a host's late
// will must not take back its newer birth).
class PrimaryHostTracker {
 public:
  // Returns whether the message was taken.
  bool update(const HostState& state);
  bool online() const { return current_ && current_->online; }
  void reset() { current_.reset(); }

 private:
  std::optional<HostState> current_;
};

}  // namespace fieldgate::sparkplug
