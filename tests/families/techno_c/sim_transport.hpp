#pragma once

// The shared fake line (tests/harness/fake_line.hpp) connecting TechnoFamily::transact() to the
// simulator's I/O-free exchange in process, on real time: writes go to the exchange, reads
// return its replies when they are due (a capital move's handshake only once the simulated
// motion has ended).

#include "fake_line.hpp"
#include "sim/techno/exchange.hpp"

namespace fieldgate::test {

class SimTransport final : public FakeLine {
 public:
  SimTransport(asio::io_context& io, sim::techno::TechnoExchange& exchange)
      : FakeLine(io, "in-process techno simulator", 0) {
    set_far_end(
        [&exchange](std::string_view bytes) { exchange.receive(sim::SimClock::now(), bytes); });
    set_schedule({[&exchange](std::string& rx) { exchange.advance(sim::SimClock::now(), rx); },
                  [&exchange] { return exchange.next_deadline(); }});
  }
};

}  // namespace fieldgate::test
