#include "blender_process.h"

#include "phasecast_blender_driver.h"  // kBlenderDriver: blender/driver.py, embedded at build time

#include <fmt/format.h>

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <thread>
#include <vector>

extern char** environ;

namespace phasecast::precompute::detail {
namespace {

constexpr int kChildChannel = 3;  // the driver opens its socket on this descriptor

// A descriptor above the child's fixed ones, so dup2 onto them always copies.
int above_fixed(int fd) {
  if (fd > kChildChannel) return fd;
  const int moved = fcntl(fd, F_DUPFD_CLOEXEC, kChildChannel + 1);
  close(fd);
  return moved;
}

int private_log() {
  const char* tmp = std::getenv("TMPDIR");
  std::string path = std::string(tmp && *tmp ? tmp : "/tmp") + "/phasecast-blender-XXXXXX";
  const int fd = mkostemp(path.data(), O_CLOEXEC);
  if (fd < 0)
    throw SimulationError(fmt::format("cannot create Blender's log in {}: {}", path, strerror(errno)));
  unlink(path.c_str());  // gone with the last descriptor
  return above_fixed(fd);
}

}  // namespace

std::filesystem::path blender_executable() {
  if (const char* chosen = std::getenv("PHASECAST_BLENDER"); chosen && *chosen) {
    if (access(chosen, X_OK) != 0)
      throw SimulationError(fmt::format("PHASECAST_BLENDER={} is not an executable file", chosen));
    return chosen;
  }
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const auto candidate = std::filesystem::path(dir.empty() ? "." : dir) / "blender";
    std::error_code ignored;
    if (std::filesystem::is_regular_file(candidate, ignored) && access(candidate.c_str(), X_OK) == 0)
      return candidate;
  }
  throw SimulationError(
      "Blender is not installed (no 'blender' on the PATH): install Debian's package 'blender' "
      "(scripts/install-deps does) or set PHASECAST_BLENDER to its executable");
}

BlenderProcess::BlenderProcess(const std::filesystem::path& blend, const std::string& mode,
                               const std::string& config, double timeout_seconds)
    : blend_(blend), timeout_(timeout_seconds) {
  const std::filesystem::path executable = blender_executable();
  int pair[2];
  if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, pair) != 0)
    throw SimulationError(fmt::format("socketpair for Blender: {}", strerror(errno)));
  channel_ = pair[0];
  const int child_end = above_fixed(pair[1]);
  try {
    log_ = private_log();
  } catch (...) {
    close(channel_), close(child_end);
    throw;
  }

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, log_, 1);
  posix_spawn_file_actions_adddup2(&actions, log_, 2);
  posix_spawn_file_actions_adddup2(&actions, child_end, kChildChannel);
  posix_spawn_file_actions_addclosefrom_np(&actions, kChildChannel + 1);  // HDF5's, MPI's: not Blender's
  std::vector<std::string> args = {executable.string(),
                                   "-b",
                                   blend.string(),
                                   "--factory-startup",
                                   "--python-expr",
                                   kBlenderDriver,
                                   "--",
                                   mode,
                                   config};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const int spawned = posix_spawn(&pid_, executable.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(child_end);
  if (spawned != 0) {
    pid_ = -1;
    close(channel_), close(log_);
    throw SimulationError(fmt::format("cannot start {}: {}", executable.string(), strerror(spawned)));
  }
}

BlenderProcess::~BlenderProcess() {
  if (channel_ >= 0) {
    send(channel_, "quit\n", 5, MSG_NOSIGNAL);
    close(channel_);
  }
  if (pid_ > 0) {
    // The driver exits on "quit" or on the closed socket; a stuck Blender is killed.
    for (int i = 0; i < 50; ++i) {
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (pid_ > 0) kill(pid_, SIGKILL), waitpid(pid_, nullptr, 0);
  }
  if (log_ >= 0) close(log_);
}

std::string BlenderProcess::last_lines(int count) const {
  std::string text;
  const off_t size = lseek(log_, 0, SEEK_END);
  const off_t from = std::max<off_t>(0, size - 4096);
  text.resize(static_cast<size_t>(size - from));
  if (pread(log_, text.data(), text.size(), from) < 0) return "(its log cannot be read)";
  std::vector<std::string> lines;
  std::stringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.find_first_not_of(" \t\r") != std::string::npos) lines.push_back(line);
  std::string out;
  for (size_t i = lines.size() > static_cast<size_t>(count) ? lines.size() - count : 0; i < lines.size(); ++i)
    out += (out.empty() ? "" : " | ") + lines[i];
  return out.empty() ? "(it printed nothing)" : out;
}

void BlenderProcess::fail(const std::string& what) {
  if (pid_ > 0) kill(pid_, SIGKILL), waitpid(pid_, nullptr, 0), pid_ = -1;
  throw SimulationError(
      fmt::format("Blender on {}: {}; its last lines: {}", blend_.string(), what, last_lines(4)));
}

std::string BlenderProcess::exit_description() {
  int status = 0;
  pid_t done = 0;
  for (int i = 0; i < 100 && (done = waitpid(pid_, &status, WNOHANG)) == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  if (done != pid_) return "it closed its channel";
  pid_ = -1;
  if (WIFSIGNALED(status)) return fmt::format("it was killed by signal {}", WTERMSIG(status));
  return fmt::format("it exited with status {}", WEXITSTATUS(status));
}

void BlenderProcess::wait_readable() {
  pollfd p{channel_, POLLIN, 0};
  const int ms = static_cast<int>(std::min(timeout_ * 1000, 2e9));
  int ready;
  do ready = poll(&p, 1, ms);
  while (ready < 0 && errno == EINTR);
  if (ready == 0) fail(fmt::format("no answer within {} s ([simulator] timeout)", timeout_));
  if (ready < 0) fail(fmt::format("poll: {}", strerror(errno)));
}

void BlenderProcess::read_exact(void* out, std::size_t bytes) {
  auto* dst = static_cast<char*>(out);
  const std::size_t buffered = std::min(bytes, buffer_.size());
  std::memcpy(dst, buffer_.data(), buffered);
  buffer_.erase(0, buffered);
  for (std::size_t got = buffered; got < bytes;) {
    wait_readable();
    const ssize_t n = recv(channel_, dst + got, bytes - got, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail(exit_description());
    got += static_cast<std::size_t>(n);
  }
}

std::string BlenderProcess::read_line() {
  for (;;) {
    if (const auto end = buffer_.find('\n'); end != std::string::npos) {
      std::string line = buffer_.substr(0, end);
      buffer_.erase(0, end + 1);
      return line;
    }
    wait_readable();
    char chunk[65536];
    const ssize_t n = recv(channel_, chunk, sizeof chunk, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail(exit_description());
    buffer_.append(chunk, static_cast<size_t>(n));
  }
}

void BlenderProcess::write(const std::string& text) {
  for (std::size_t sent = 0; sent < text.size();) {
    const ssize_t n = send(channel_, text.data() + sent, text.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail("it stopped listening");
    sent += static_cast<std::size_t>(n);
  }
}

}  // namespace phasecast::precompute::detail
