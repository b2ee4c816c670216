#pragma once

#include <fmt/format.h>

#include <optional>
#include <string_view>

namespace fieldgate::log {

// syslog priorities; when stderr is the journal (JOURNAL_STREAM names it) each line starts with
// <N> so journald files it correctly; on a terminal or a file the lines are plain.
enum class Level { error = 3, warning = 4, notice = 5, info = 6, debug = 7 };

// Whether lines carry <N> prefixes (detected once from JOURNAL_STREAM); `force` overrides it.
bool journal_prefixes(std::optional<bool> force = std::nullopt);

void set_verbosity(Level most_verbose);
bool enabled(Level level);
void write(Level level, std::string_view message);

template <typename... Args>
void error(fmt::format_string<Args...> f, Args&&... args) {
  if (enabled(Level::error)) write(Level::error, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void warning(fmt::format_string<Args...> f, Args&&... args) {
  if (enabled(Level::warning)) write(Level::warning, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void notice(fmt::format_string<Args...> f, Args&&... args) {
  if (enabled(Level::notice)) write(Level::notice, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void info(fmt::format_string<Args...> f, Args&&... args) {
  if (enabled(Level::info)) write(Level::info, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void debug(fmt::format_string<Args...> f, Args&&... args) {
  if (enabled(Level::debug)) write(Level::debug, fmt::format(f, std::forward<Args>(args)...));
}

}  // namespace fieldgate::log
