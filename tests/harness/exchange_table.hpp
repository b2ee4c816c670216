#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <string>
#include <vector>

namespace fieldgate::test {

// One line sent to a simulated unit, the exact reply it must give, why (shown on failure), and
// for a unit run on injected time, the time it is sent at (seconds since the bench started).
struct Exchange {
  std::string command;
  std::string reply;
  std::string why = {};
  double seconds = 0;
};

// Sends each exchange in order to `unit` (anything with send(command) returning the reply, and
// send(command, seconds) where a row is timed), so a test reads as a transcript; a failing row
// names its index and command.
template <class Unit>
void expect_replies(Unit& unit, const std::vector<Exchange>& exchanges) {
  for (std::size_t row = 0; row < exchanges.size(); ++row) {
    const Exchange& exchange = exchanges[row];
    SCOPED_TRACE("row " + std::to_string(row) + ": " + exchange.command);
    if constexpr (requires { unit.send(exchange.command, exchange.seconds); })
      EXPECT_EQ(unit.send(exchange.command, exchange.seconds), exchange.reply) << exchange.why;
    else
      EXPECT_EQ(unit.send(exchange.command), exchange.reply) << exchange.why;
  }
}

}  // namespace fieldgate::test
