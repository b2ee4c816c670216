#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate {

// What the daemon tells `fieldgate reload` (and anyone else) about its configuration: written
// at start-up and after every SIGHUP to a file in its runtime directory (RuntimeDirectory=, so
// /run/fieldgate/reload-verdict), replaced atomically. systemd 252 takes `ExecReload=`'s exit
// status as the reload's result but cannot hear a verdict from the daemon itself, so the
// helper sends SIGHUP and waits here for a verdict with a higher `reload` number.
struct ReloadVerdict {
  enum class Result { started, accepted, rejected };

  long pid = 0;
  uint64_t reload = 0;  // SIGHUPs handled so far; 0 after start-up
  Result result = Result::started;
  std::string config_file;     // the file the daemon reads
  uint64_t config_number = 1;  // configurations put in force so far (1: the one started with)
  std::string config_id;       // fingerprint of the text in force (config_fingerprint)
  std::vector<std::string> messages;  // the reload's summary, or every error of a refusal

  // "config #2 (1a2b3c4d)": how StatusText and the log name the configuration in force.
  std::string in_force() const;
};

std::string_view to_string(ReloadVerdict::Result result);
std::string to_text(const ReloadVerdict& verdict);
// nullopt when the text is not a complete verdict (a missing or unknown key's value).
std::optional<ReloadVerdict> parse_verdict(std::string_view text);

// Writes to a temporary file beside `path` and renames it over `path`: a reader sees the old
// verdict or the new one, never half of one. Returns false (and sets `error`) on failure.
bool write_verdict_file(const std::filesystem::path& path, const ReloadVerdict& verdict,
                        std::string& error);
std::optional<ReloadVerdict> read_verdict_file(const std::filesystem::path& path);

// A short fingerprint of a configuration's text (FNV-1a, 64 bits, as 16 hex digits), so the
// operator can tell which edit is in force; empty when the file cannot be read.
std::string config_fingerprint(const std::filesystem::path& path);

// The runtime directory: `option` when given, else $RUNTIME_DIRECTORY (set by systemd for
// RuntimeDirectory=; the first of several), else none.
std::optional<std::filesystem::path> runtime_directory(const std::string& option);
inline constexpr const char* kVerdictFileName = "reload-verdict";

// Waits for a verdict whose reload number is above `after`: reads with `read` and, while there
// is none, calls `pause` (which returns false when the wait is over). The clock lives in
// `pause`, so a test drives the wait without one.
std::optional<ReloadVerdict> wait_for_verdict(
    const std::function<std::optional<ReloadVerdict>()>& read, uint64_t after,
    const std::function<bool()>& pause);

}  // namespace fieldgate
