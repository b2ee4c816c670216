// Runs the real fieldgate-sim-copley binary on a PTY, as the gateway will.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "sim/common/pty_port.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

// Waits until fd has input or the deadline passes and appends what one read gives to `into`;
// false on timeout, end of file or error.
bool read_more(int fd, std::string& into, Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
  pollfd ready{fd, POLLIN, 0};
  if (left.count() <= 0 || ::poll(&ready, 1, static_cast<int>(left.count())) <= 0) return false;
  char buffer[256];
  const ssize_t n = ::read(fd, buffer, sizeof buffer);
  if (n <= 0) return false;
  into.append(buffer, static_cast<std::size_t>(n));
  return true;
}

// The simulator as a child process with its stdin and stdout on pipes (the control channel).
class Simulator {
 public:
  explicit Simulator(std::vector<std::string> arguments) {
    int to_child[2];
    int from_child[2];
    if (::pipe2(to_child, O_CLOEXEC) != 0 || ::pipe2(from_child, O_CLOEXEC) != 0) {
      throw std::runtime_error("pipe");
    }
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, to_child[0], STDIN_FILENO);
    posix_spawn_file_actions_adddup2(&actions, from_child[1], STDOUT_FILENO);
    arguments.insert(arguments.begin(), FIELDGATE_SIM_COPLEY);
    std::vector<char*> argv;
    for (auto& a : arguments) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int error =
        ::posix_spawn(&pid_, FIELDGATE_SIM_COPLEY, &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(to_child[0]);
    ::close(from_child[1]);
    control_in_ = to_child[1];
    control_out_ = from_child[0];
    if (error != 0) throw std::runtime_error("posix_spawn failed");
  }

  ~Simulator() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
    ::close(control_in_);
    ::close(control_out_);
  }

  // One line of the simulator's stdout, without the newline; "" on timeout or end of file.
  std::string read_line(std::chrono::milliseconds timeout = 5s) {
    const auto deadline = Clock::now() + timeout;
    while (true) {
      const auto newline = stdout_.find('\n');
      if (newline != std::string::npos) {
        std::string line = stdout_.substr(0, newline);
        stdout_.erase(0, newline + 1);
        return line;
      }
      if (!read_more(control_out_, stdout_, deadline)) return "";
    }
  }

  // Sends a control command and returns its reply line.
  std::string control(const std::string& command) {
    const std::string line = command + "\n";
    if (::write(control_in_, line.data(), line.size()) != static_cast<ssize_t>(line.size())) {
      return "(write failed)";
    }
    return read_line();
  }

  void terminate() { ::kill(pid_, SIGTERM); }

  // Exit status, or -1 if the process is still running after `timeout`.
  int wait_exit(std::chrono::milliseconds timeout = 5s) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(10ms);
    }
    return -1;
  }

 private:
  pid_t pid_ = -1;
  int control_in_ = -1;
  int control_out_ = -1;
  std::string stdout_;
};

// The host end of the serial link, opened through the simulator's symlink like a real port.
class HostPort {
 public:
  explicit HostPort(const fs::path& path, speed_t speed = B9600) {
    fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (fd_ < 0) throw std::runtime_error("open " + path.string());
    set_speed(speed);
  }
  ~HostPort() { ::close(fd_); }

  // Drops whatever arrived while nobody read; the simulator keeps the PTY open, so bytes sent
  // while the port was closed are still queued (a gateway should flush on open anyway).
  void flush_input() { ::tcflush(fd_, TCIFLUSH); }

  void set_speed(speed_t speed) {
    termios tio{};
    ::tcgetattr(fd_, &tio);
    ::cfmakeraw(&tio);
    ::cfsetspeed(&tio, speed);
    ::tcsetattr(fd_, TCSANOW, &tio);
  }

  // Sends a request and reads up to the reply's CR; "" when nothing complete came in time.
  std::string transact(const std::string& request, std::chrono::milliseconds timeout = 2s) {
    if (::write(fd_, request.data(), request.size()) != static_cast<ssize_t>(request.size())) {
      return "(write failed)";
    }
    std::string reply;
    const auto deadline = Clock::now() + timeout;
    while (reply.empty() || reply.back() != '\r') {
      if (!read_more(fd_, reply, deadline)) return "";
    }
    return reply;
  }

  // Round-trip time of a request, the shortest of `tries`.
  Clock::duration round_trip(const std::string& request, int tries = 3) {
    auto best = Clock::duration::max();
    for (int k = 0; k < tries; ++k) {
      const auto start = Clock::now();
      EXPECT_NE(transact(request), "");
      best = std::min(best, Clock::now() - start);
    }
    return best;
  }

 private:
  int fd_ = -1;
};

class CopleyPty : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/fieldgate-sim-test-XXXXXX";
    ASSERT_NE(::mkdtemp(pattern), nullptr);
    dir_ = pattern;
    link_ = dir_ / "copley0";
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  fs::path link_;
};

TEST_F(CopleyPty, PtyPortSurvivesTheHostClosingThePort) {
  {
    fieldgate::sim::PtyPort port(link_);
    ASSERT_EQ(fs::read_symlink(link_), port.slave_name());
    char buffer[16];
    for (int round = 0; round < 2; ++round) {
      const int host = ::open(link_.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
      ASSERT_GE(host, 0);
      termios tio{};
      ::tcgetattr(host, &tio);
      EXPECT_EQ(tio.c_lflag & (ICANON | ECHO), 0u) << "the slave starts in raw mode";
      ASSERT_EQ(::write(host, "g\r", 2), 2);
      pollfd master{port.master_fd(), POLLIN, 0};
      ASSERT_EQ(::poll(&master, 1, 1000), 1);
      EXPECT_EQ(port.read_some(buffer), 2u);
      EXPECT_EQ(port.write_some("ok\r"), 3u);
      pollfd slave{host, POLLIN, 0};
      ASSERT_EQ(::poll(&slave, 1, 1000), 1);
      EXPECT_EQ(::read(host, buffer, sizeof buffer), 3);
      ::close(host);
      // With the simulator's own slave descriptor open, the master neither hangs up nor
      // reads EIO while the host has the port closed.
      master.revents = 0;
      EXPECT_EQ(::poll(&master, 1, 50), 0);
      EXPECT_EQ(port.read_some(buffer), 0u);
    }
  }
  EXPECT_FALSE(fs::exists(fs::symlink_status(link_))) << "the link goes with the port";
}

TEST_F(CopleyPty, AnswersOnTheLinkAndObeysTheControlChannel) {
  Simulator sim({"--link", link_.string(), "--nodes", "0,3"});
  const std::string ready = sim.read_line();
  ASSERT_EQ(ready.rfind("ready " + link_.string() + " /dev/pts/", 0), 0u) << ready;
  ASSERT_TRUE(fs::is_symlink(link_));

  {
    HostPort port(link_);
    EXPECT_EQ(port.transact("g r0x32\r"), "v 0\r");
    EXPECT_EQ(port.transact("3 g r0x32\r"), "v 0\r");
    EXPECT_EQ(port.transact("t2\r"), "e 33\r");
    EXPECT_EQ(sim.control("node-off 3"), "ok node-off 3");
    EXPECT_EQ(port.transact("3 g r0x32\r"), "e 32\r");
    EXPECT_EQ(sim.control("node-on 3"), "ok node-on 3");
    EXPECT_EQ(port.transact("3 g r0x32\r"), "v 0\r");
    EXPECT_EQ(sim.control("silence on"), "ok silence on");
    EXPECT_EQ(port.transact("g r0x32\r", 200ms), "");
    EXPECT_EQ(sim.control("silence off"), "ok silence off");
    EXPECT_EQ(sim.control("truncate 1"), "ok truncate 1");
    EXPECT_EQ(port.transact("g r0x6b\r", 200ms), "") << "half a reply, no CR";
  }
  {
    // The simulator holds the slave open: closing and reopening the port loses nothing.
    HostPort port(link_);
    port.flush_input();
    EXPECT_EQ(port.transact("s r0x24 21\r"), "ok\r");
    EXPECT_EQ(port.transact("g r0xa0\r"), "v 0\r");
  }
  EXPECT_EQ(sim.control("quit"), "ok quit");
  EXPECT_EQ(sim.wait_exit(), 0);
  EXPECT_FALSE(fs::exists(fs::symlink_status(link_))) << "the link is removed on exit";
}

TEST_F(CopleyPty, EmulatesWireTimeAtTheAmplifiersBaud) {
  Simulator sim({"--link", link_.string(), "--emulate-wire", "--turnaround-us", "2000"});
  ASSERT_EQ(sim.read_line().rfind("ready", 0), 0u);
  HostPort port(link_);
  // "g r0x32\r" + "v 0\r" = 12 characters of 10 bits at 9600 baud, plus the turnaround.
  const auto slow = port.round_trip("g r0x32\r");
  EXPECT_GE(slow, 12 * 10 * 1s / 9600 + 2ms);
  EXPECT_EQ(port.transact("s r0x90 115200\r"), "ok\r");
  port.set_speed(B115200);
  const auto fast = port.round_trip("g r0x32\r");
  EXPECT_GE(fast, 12 * 10 * 1s / 115200 + 2ms);
  EXPECT_LT(fast, slow);
  EXPECT_EQ(sim.control("reset 0"), "ok reset 0");
  port.set_speed(B9600);
  EXPECT_GE(port.round_trip("g r0x32\r", 1), 12 * 10 * 1s / 9600 + 2ms) << "back at 9600";
}

TEST_F(CopleyPty, SignalRemovesTheLink) {
  Simulator sim({"--link", link_.string()});
  ASSERT_EQ(sim.read_line().rfind("ready", 0), 0u);
  ASSERT_TRUE(fs::is_symlink(link_));
  // A control reply proves the loop (and its signal handling) is running.
  ASSERT_EQ(sim.control("delay 0"), "ok delay 0");
  sim.terminate();
  EXPECT_EQ(sim.wait_exit(), 0);
  EXPECT_FALSE(fs::exists(fs::symlink_status(link_)));
}

TEST_F(CopleyPty, RefusesToReplaceARegularFile) {
  std::ofstream(link_) << "precious\n";
  Simulator sim({"--link", link_.string()});
  EXPECT_EQ(sim.wait_exit(), 1);
  std::ifstream in(link_);
  std::string content;
  std::getline(in, content);
  EXPECT_EQ(content, "precious");
}

TEST_F(CopleyPty, ReplacesAStaleSymlink) {
  fs::create_symlink("/dev/pts/does-not-exist", link_);
  Simulator sim({"--link", link_.string()});
  ASSERT_EQ(sim.read_line().rfind("ready", 0), 0u);
  EXPECT_NE(fs::read_symlink(link_).string(), "/dev/pts/does-not-exist");
  HostPort port(link_);
  EXPECT_EQ(port.transact("g r0x32\r"), "v 0\r");
}

}  // namespace
