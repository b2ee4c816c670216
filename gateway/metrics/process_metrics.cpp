#include "gateway/metrics/process_metrics.hpp"

#include <unistd.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <vector>

namespace fieldgate {

namespace {

std::string read_file(const char* path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Seconds since the epoch when the system booted (/proc/stat btime).
std::optional<double> boot_time() {
  std::istringstream in(read_file("/proc/stat"));
  std::string key;
  while (in >> key) {
    if (key == "btime") {
      double t = 0;
      if (in >> t) return t;
      return std::nullopt;
    }
    in.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
  }
  return std::nullopt;
}

}  // namespace

bool parse_proc_stat(std::string_view text, long ticks_per_second, long page_size, ProcStat& out) {
  // The command name may hold spaces and parentheses: the fields start after the last ')'.
  const auto close = text.rfind(')');
  if (close == std::string_view::npos || ticks_per_second <= 0) return false;
  std::istringstream in{std::string(text.substr(close + 1))};
  std::vector<std::string> fields;  // fields[0] is field 3 (state)
  for (std::string f; in >> f;) fields.push_back(f);
  // utime 14, stime 15, starttime 22, rss 24 (proc(5), 1-based)
  if (fields.size() < 22) return false;
  try {
    const double utime = std::stod(fields[14 - 3]);
    const double stime = std::stod(fields[15 - 3]);
    out.cpu_seconds = (utime + stime) / static_cast<double>(ticks_per_second);
    out.start_seconds = std::stod(fields[22 - 3]) / static_cast<double>(ticks_per_second);
    out.resident_bytes = std::stod(fields[24 - 3]) * static_cast<double>(page_size);
  } catch (const std::exception&) {
    return false;
  }
  return true;
}

std::string render_process_metrics() {
  std::string text;
  const auto sample = [&](std::string_view name, std::string_view type, std::string_view help,
                          double value) {
    text += fmt::format("# HELP {} {}\n# TYPE {} {}\n{} {}\n", name, help, name, type, name, value);
  };
  ProcStat stat;
  if (parse_proc_stat(read_file("/proc/self/stat"), sysconf(_SC_CLK_TCK), sysconf(_SC_PAGESIZE),
                      stat)) {
    sample("process_cpu_seconds_total", "counter", "Total user and system CPU time in seconds.",
           stat.cpu_seconds);
    sample("process_resident_memory_bytes", "gauge", "Resident memory size in bytes.",
           stat.resident_bytes);
    if (const auto boot = boot_time())
      sample("process_start_time_seconds", "gauge",
             "Start time of the process since the Unix epoch in seconds.",
             *boot + stat.start_seconds);
  }
  std::error_code ec;
  std::size_t fds = 0;
  for (std::filesystem::directory_iterator it("/proc/self/fd", ec), end; !ec && it != end;
       it.increment(ec))
    ++fds;
  // The directory iterator holds one descriptor of its own while counting.
  if (!ec && fds > 0)
    sample("process_open_fds", "gauge", "Number of open file descriptors.",
           static_cast<double>(fds - 1));
  if (const long max = sysconf(_SC_OPEN_MAX); max > 0)
    sample("process_max_fds", "gauge", "Maximum number of open file descriptors.",
           static_cast<double>(max));
  return text;
}

}  // namespace fieldgate
