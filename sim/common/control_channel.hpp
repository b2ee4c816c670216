#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate::sim {

// Misbehaviour a test can switch on while the simulator runs. The line loop applies it to every
// request, whichever family is simulated.
struct FaultInjection {
  bool silence = false;            // requests are discarded unheard, nothing is executed
  unsigned garbage_replies = 0;    // the next N replies become random bytes
  unsigned truncated_replies = 0;  // the next N replies lose their second half and terminator
  std::chrono::milliseconds reply_delay{0};  // added before every reply
  // The next request containing this text is executed and its reply lost on the way (the
  // device ran it; the host hears nothing). Empty: off.
  std::string swallow_reply_to;
  // Random faults on every reply while `chaos` is on (percentages; the request is still
  // executed): late by `late`, dropped, garbled, truncated. Seeded, so a failing run repeats.
  struct Chaos {
    bool on = false;
    std::uint32_t seed = 1;
    unsigned late_percent = 0;
    unsigned drop_percent = 0;
    unsigned garble_percent = 0;
    unsigned truncate_percent = 0;
    std::chrono::milliseconds late{0};
    unsigned generation = 0;  // bumped by every chaos command, so the line reseeds
  } chaos;
};

// Family-specific control commands: `verb` with its arguments. Returns the reply line ("ok…" or
// "error: …"), or nullopt when the verb is not the family's.
using FamilyControl = std::function<std::optional<std::string>(
    std::string_view verb, std::span<const std::string> arguments)>;

// Decimal or 0x-prefixed hex, optionally negative; nullopt if `text` is anything else.
std::optional<long long> parse_control_integer(std::string_view text);

// Line commands on the simulator's stdin, one reply line each on stdout, so a test can inject
// faults at runtime and knows when a command has taken effect.
//
// Generic commands:  silence on|off, garbage N, truncate N, delay MS, swallow TEXT,
//                    chaos SEED LATE% DROP% GARBLE% TRUNCATE% LATE_MS | chaos off, help, quit.
// Everything else goes to the family handler.
class ControlChannel {
 public:
  ControlChannel(int input_fd, int output_fd, FaultInjection& faults, FamilyControl family = {},
                 std::string family_help = {});

  // Descriptor to poll for POLLIN; -1 once the input has reached end of file.
  int input_fd() const { return input_fd_; }
  // Reads once (poll said it would not block) and executes every complete line.
  void on_readable();
  // Executes one command line and returns its reply, without the newline.
  std::string execute(std::string_view line);

  bool quit_requested() const { return quit_; }

 private:
  void reply(std::string_view line);

  int input_fd_;
  int output_fd_;
  FaultInjection& faults_;
  FamilyControl family_;
  std::string family_help_;
  std::string pending_;
  bool quit_ = false;
};

}  // namespace fieldgate::sim
