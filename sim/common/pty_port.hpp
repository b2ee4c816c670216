#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

namespace fieldgate::sim {

// A pseudo-terminal standing in for a serial port. The simulator owns the master side; the
// gateway opens the slave, usually through a symlink at a path of the caller's choosing
// (e.g. /tmp/copley0), exactly as it would open /dev/ttyS0.
//
// The simulator keeps one slave descriptor open for its whole life. Without it the master reads
// EIO and polls POLLHUP whenever the gateway closes the port, and the slave's termios settings
// would be lost between the gateway's close and reopen.
class PtyPort {
 public:
  // Creates the PTY, puts the slave in raw mode at 9600 8N1 and, unless link_path is empty,
  // points a symlink at the slave. An existing symlink is replaced; anything else at link_path
  // is left alone and the constructor throws. Throws std::system_error on OS failures.
  explicit PtyPort(std::filesystem::path link_path = {});
  ~PtyPort();

  PtyPort(const PtyPort&) = delete;
  PtyPort& operator=(const PtyPort&) = delete;

  // Non-blocking master descriptor, for poll().
  int master_fd() const { return master_; }
  // /dev/pts/N.
  const std::string& slave_name() const { return slave_name_; }
  const std::filesystem::path& link_path() const { return link_path_; }

  // Reads what the host has written; 0 when nothing is pending.
  std::size_t read_some(std::span<char> buffer);
  // Writes as much as the PTY accepts; the rest is the caller's to retry on POLLOUT.
  std::size_t write_some(std::string_view bytes);

 private:
  int master_ = -1;
  int slave_keepalive_ = -1;
  std::string slave_name_;
  std::filesystem::path link_path_;
};

}  // namespace fieldgate::sim
