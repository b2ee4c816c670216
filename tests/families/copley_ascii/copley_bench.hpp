#pragma once

#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "sim/copley/amplifier_network.hpp"
#include "tests/sim/sim_time.hpp"

namespace fieldgate::sim::copley::test {

using sim::test::at;

// An amplifier network driven with injected time: send("g r0x32", 1.5) is the request
// "g r0x32\r" arriving 1.5 s after the simulated power-up.
struct CopleyBench {
  explicit CopleyBench(NetworkOptions options = {}) : network(std::move(options), at(0)) {}

  DeviceReply exchange(std::string_view command, double seconds = 0) {
    return network.handle(std::string(command) + "\r", at(seconds));
  }
  std::string send(std::string_view command, double seconds = 0) {
    return exchange(command, seconds).bytes;
  }
  // The values of a `v …` reply; empty if the reply is anything else.
  std::vector<std::int64_t> values(std::string_view command, double seconds = 0) {
    const std::string reply = send(command, seconds);
    std::vector<std::int64_t> out;
    if (reply.size() < 2 || reply[0] != 'v' || reply.back() != '\r') return out;
    std::istringstream in(reply.substr(1));
    std::int64_t v;
    while (in >> v) out.push_back(v);
    return out;
  }
  std::int64_t value(std::string_view command, double seconds = 0) {
    const auto v = values(command, seconds);
    return v.size() == 1 ? v[0] : INT64_MIN;
  }
  std::string control(const std::string& line, double seconds = 0) {
    std::istringstream in(line);
    std::string verb;
    in >> verb;
    std::vector<std::string> arguments;
    for (std::string word; in >> word;) arguments.push_back(word);
    std::optional<std::uint32_t> baud;
    last_control_baud.reset();
    auto reply = network.control(verb, arguments, at(seconds), baud);
    last_control_baud = baud;
    return reply.value_or("(not a family command)");
  }

  AmplifierNetwork network;
  std::optional<std::uint32_t> last_control_baud;
};

inline NetworkOptions nodes(std::vector<int> ids) {
  NetworkOptions options;
  options.nodes = std::move(ids);
  return options;
}

constexpr std::int64_t bit(int n) {
  return std::int64_t{1} << n;
}

}  // namespace fieldgate::sim::copley::test
