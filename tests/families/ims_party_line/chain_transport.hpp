#pragma once

// The shared fake line (tests/harness/fake_line.hpp) whose far end is the simulator's party
// line, in process: the family's transact() runs against simulated units without a PTY.
// Replies the units delay (a queued index, S) arrive after their delay.

#include <string>

#include "fake_line.hpp"
#include "sim/ims/party_line.hpp"

namespace fieldgate::test {

class ChainTransport final : public FakeLine {
 public:
  ChainTransport(asio::io_context& io, sim::ims::PartyLineOptions options)
      : FakeLine(io, "simulated party line", 1e6 * 10 / 9600),
        chain_(
            std::move(options), faults_, [] { return sim::SimClock::now(); },
            sim::SimClock::now()) {
    set_far_end([this](std::string_view bytes) { hear(bytes); });
  }

  sim::ims::PartyLine& chain() { return chain_; }
  sim::FaultInjection& faults() { return faults_; }

 private:
  void hear(std::string_view bytes) {
    if (!faults_.silence) deliver(chain_.echo(bytes));
    pending_.append(bytes);
    while (const std::size_t n = sim::ims::PartyLine::frame(pending_)) {
      const std::string request = pending_.substr(0, n);
      pending_.erase(0, n);
      if (faults_.silence) continue;
      const sim::DeviceReply reply = chain_.respond(request, sim::SimClock::now());
      // `delay MS` of the control channel holds results and completions, not echoes.
      deliver(reply.bytes, reply.extra_delay + faults_.reply_delay);
    }
  }

  sim::FaultInjection faults_;
  sim::ims::PartyLine chain_;
  std::string pending_;
};

}  // namespace fieldgate::test
