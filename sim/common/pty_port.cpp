#include "sim/common/pty_port.hpp"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <stdexcept>
#include <system_error>

namespace fieldgate::sim {
namespace {

[[noreturn]] void throw_errno(const std::string& what) {
  throw std::system_error(errno, std::generic_category(), what);
}

void replace_symlink(const std::filesystem::path& link, const std::string& target) {
  namespace fs = std::filesystem;
  const auto status = fs::symlink_status(link);
  if (fs::exists(status) && !fs::is_symlink(status)) {
    throw std::runtime_error("refusing to replace " + link.string() + ": it is not a symlink");
  }
  // Create beside the link and rename over it, so a gateway never sees the path missing.
  fs::path temporary = link;
  temporary += ".tmp" + std::to_string(::getpid());
  fs::remove(temporary);
  fs::create_symlink(target, temporary);
  fs::rename(temporary, link);
}

}  // namespace

PtyPort::PtyPort(std::filesystem::path link_path) : link_path_(std::move(link_path)) {
  master_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (master_ < 0) throw_errno("posix_openpt");
  try {
    if (::grantpt(master_) != 0) throw_errno("grantpt");
    if (::unlockpt(master_) != 0) throw_errno("unlockpt");
    char name[128];
    if (::ptsname_r(master_, name, sizeof name) != 0) throw_errno("ptsname_r");
    slave_name_ = name;

    slave_keepalive_ = ::open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (slave_keepalive_ < 0) throw_errno("open " + slave_name_);
    termios tio{};
    if (::tcgetattr(slave_keepalive_, &tio) != 0) throw_errno("tcgetattr");
    ::cfmakeraw(&tio);
    ::cfsetspeed(&tio, B9600);
    tio.c_cflag |= CLOCAL | CREAD;
    if (::tcsetattr(slave_keepalive_, TCSANOW, &tio) != 0) throw_errno("tcsetattr");

    const int flags = ::fcntl(master_, F_GETFL);
    if (flags < 0 || ::fcntl(master_, F_SETFL, flags | O_NONBLOCK) != 0) throw_errno("fcntl");

    if (!link_path_.empty()) replace_symlink(link_path_, slave_name_);
  } catch (...) {
    if (slave_keepalive_ >= 0) ::close(slave_keepalive_);
    ::close(master_);
    throw;
  }
}

PtyPort::~PtyPort() {
  if (!link_path_.empty()) {
    std::error_code ignored;
    // Only remove the link if it still points at our slave; a newer simulator may own it now.
    const auto target = std::filesystem::read_symlink(link_path_, ignored);
    if (!ignored && target == slave_name_) std::filesystem::remove(link_path_, ignored);
  }
  ::close(slave_keepalive_);
  ::close(master_);
}

std::size_t PtyPort::read_some(std::span<char> buffer) {
  const ssize_t n = ::read(master_, buffer.data(), buffer.size());
  if (n >= 0) return static_cast<std::size_t>(n);
  if (errno == EAGAIN || errno == EINTR) return 0;
  throw_errno("read " + slave_name_);
}

std::size_t PtyPort::write_some(std::string_view bytes) {
  if (bytes.empty()) return 0;
  const ssize_t n = ::write(master_, bytes.data(), bytes.size());
  if (n >= 0) return static_cast<std::size_t>(n);
  if (errno == EAGAIN || errno == EINTR) return 0;
  throw_errno("write " + slave_name_);
}

}  // namespace fieldgate::sim
