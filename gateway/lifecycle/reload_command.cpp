#include "gateway/lifecycle/reload_command.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <iostream>
#include <thread>

#include "gateway/lifecycle/daemon.hpp"
#include "gateway/lifecycle/log.hpp"
#include "gateway/lifecycle/reload_verdict.hpp"

namespace fieldgate {

namespace {

constexpr auto kPollEvery = std::chrono::milliseconds(50);

// Under systemd (ExecReload=) stderr is the journal: a refusal is filed at err, not at info.
int refuse(const std::string& why) {
  log::error("fieldgate reload: {}", why);
  return 1;
}

}  // namespace

int run_reload(const ReloadOptions& options) {
  const auto dir = runtime_directory(options.runtime_dir);
  if (!dir)
    return refuse(
        "no runtime directory (--runtime-dir, or RuntimeDirectory= in the unit), so the daemon's "
        "verdict cannot be read");
  const auto path = *dir / kVerdictFileName;
  const auto before = read_verdict_file(path);
  if (!before)
    return refuse(
        fmt::format("no verdict in {}: is the daemon running with this runtime "
                    "directory?",
                    path.string()));
  const long pid = options.pid != 0 ? options.pid : before->pid;
  if (options.pid != 0 && options.pid != before->pid)
    return refuse(fmt::format("{} was written by pid {}, not by {}", path.string(), before->pid,
                              options.pid));
  if (options.check_first && !load_config_or_report(before->config_file)) {
    return refuse(fmt::format("refused: {} stays in force", before->in_force()));
  }
  if (::kill(static_cast<pid_t>(pid), SIGHUP) != 0)
    return refuse(fmt::format("cannot signal pid {}: {}", pid, std::strerror(errno)));
  const auto deadline = std::chrono::steady_clock::now() + options.timeout;
  const auto verdict = wait_for_verdict([&] { return read_verdict_file(path); }, before->reload,
                                        [&] {
                                          if (std::chrono::steady_clock::now() >= deadline)
                                            return false;
                                          std::this_thread::sleep_for(kPollEvery);
                                          return true;
                                        });
  if (!verdict)
    return refuse(fmt::format("no verdict from pid {} within {} ms; what is in force is unknown",
                              pid, options.timeout.count()));
  if (verdict->pid != pid)
    return refuse(
        fmt::format("the verdict is from pid {}, not {}: the daemon restarted", verdict->pid, pid));
  const bool accepted = verdict->result == ReloadVerdict::Result::accepted;
  for (const auto& m : verdict->messages)
    log::write(accepted ? log::Level::notice : log::Level::error, "fieldgate reload: " + m);
  if (!accepted)
    return refuse(fmt::format("rejected by the daemon: {} stays in force", verdict->in_force()));
  std::cout << fmt::format("fieldgate reload: {} in force\n", verdict->in_force());
  return 0;
}

}  // namespace fieldgate
