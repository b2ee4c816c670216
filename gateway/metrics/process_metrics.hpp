#pragma once

#include <string>
#include <string_view>

namespace fieldgate {

// The process_* series Prometheus client libraries export (resident memory, CPU time, open
// descriptors, start time), read from /proc/self; a series whose source cannot be read is left
// out rather than reported as 0.
std::string render_process_metrics();

// Parses /proc/<pid>/stat text: fields after the parenthesised command name. Exposed for tests.
struct ProcStat {
  double cpu_seconds = 0;     // utime + stime
  double start_seconds = 0;   // since boot
  double resident_bytes = 0;  // rss pages * page size
};
bool parse_proc_stat(std::string_view text, long ticks_per_second, long page_size, ProcStat& out);

}  // namespace fieldgate
