#include "gateway/lifecycle/log.hpp"

#include <sys/stat.h>

#include <cstdio>
#include <cstdlib>
#include <string>

namespace fieldgate::log {

namespace {
Level g_verbosity = Level::info;

bool stderr_is_journal() {
  const char* stream = std::getenv("JOURNAL_STREAM");
  if (!stream) return false;
  unsigned long long device = 0;
  unsigned long long inode = 0;
  if (std::sscanf(stream, "%llu:%llu", &device, &inode) != 2) return false;
  struct stat st {};
  if (fstat(fileno(stderr), &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == device &&
         static_cast<unsigned long long>(st.st_ino) == inode;
}
}  // namespace

bool journal_prefixes(std::optional<bool> force) {
  static bool prefixes = stderr_is_journal();
  if (force) prefixes = *force;
  return prefixes;
}

void set_verbosity(Level most_verbose) {
  g_verbosity = most_verbose;
}

bool enabled(Level level) {
  return static_cast<int>(level) <= static_cast<int>(g_verbosity);
}

void write(Level level, std::string_view message) {
  std::string line = journal_prefixes() ? fmt::format("<{}>{}\n", static_cast<int>(level), message)
                                        : fmt::format("{}\n", message);
  std::fwrite(line.data(), 1, line.size(), stderr);
}

}  // namespace fieldgate::log
