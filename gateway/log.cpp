#include "gateway/log.hpp"

#include <cstdio>
#include <string>

namespace fieldgate::log {

namespace {
Level g_verbosity = Level::info;
}

void set_verbosity(Level most_verbose) {
  g_verbosity = most_verbose;
}

bool enabled(Level level) {
  return static_cast<int>(level) <= static_cast<int>(g_verbosity);
}

void write(Level level, std::string_view message) {
  std::string line = fmt::format("<{}>{}\n", static_cast<int>(level), message);
  std::fwrite(line.data(), 1, line.size(), stderr);
}

}  // namespace fieldgate::log
