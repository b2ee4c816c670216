#pragma once

#include <chrono>
#include <string>

namespace fieldgate {

// `fieldgate reload`: systemd's ExecReload=. Validates the running daemon's configuration file
// as `fieldgate check` does (no signal is sent when it fails), sends SIGHUP, and waits for the
// daemon's verdict in its runtime directory. Exit status 0 only when the daemon has put the new
// configuration in force, so `systemctl reload` fails when it did not.
struct ReloadOptions {
  long pid = 0;             // the daemon ($MAINPID); 0: the pid in the verdict file
  std::string runtime_dir;  // empty: $RUNTIME_DIRECTORY
  bool check_first = true;  // --no-check: leave the verdict to the daemon alone
  std::chrono::milliseconds timeout{std::chrono::seconds(30)};
};

int run_reload(const ReloadOptions& options);

}  // namespace fieldgate
