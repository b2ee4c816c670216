#pragma once

// The shared fake line (tests/harness/fake_line.hpp) for running WhedcoFamily::transact() in
// process: every write goes to a responder (the simulated CMC line, or a script), whose answer
// becomes readable at once.

#include <deque>
#include <functional>
#include <string>

#include "fake_line.hpp"
#include "sim/whedco/cmc_line.hpp"

namespace fieldgate::test {

class LineTransport final : public FakeLine {
 public:
  using Responder = std::function<std::string(std::string_view written)>;

  LineTransport(asio::io_context& io, Responder responder)
      : FakeLine(io, "in-process CMC line", 1e6 * 10 / 38400) {
    set_far_end([this, responder = std::move(responder)](std::string_view written) mutable {
      deliver(responder(written));
    });
  }

  // The simulated line: echo as the bytes arrive, then each complete request's reply.
  static Responder simulated(sim::whedco::CmcLine& line) {
    return [&line, pending = std::string()](std::string_view written) mutable {
      std::string out = line.echo(written);
      pending.append(written);
      while (const std::size_t n = sim::whedco::CmcLine::frame(pending)) {
        out += line.handle(pending.substr(0, n), sim::SimClock::now()).bytes;
        pending.erase(0, n);
      }
      return out;
    };
  }

  // Canned replies, one per write, in order; writes beyond the script get silence.
  static Responder scripted(std::deque<std::string> replies) {
    return [replies = std::move(replies)](std::string_view) mutable {
      if (replies.empty()) return std::string();
      std::string r = replies.front();
      replies.pop_front();
      return r;
    };
  }
};

}  // namespace fieldgate::test
