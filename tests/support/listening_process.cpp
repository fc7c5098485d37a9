#include "listening_process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string_view>

namespace phasecast::testing {
namespace {

// Reads what is available on `fd` within `ms`; false at end of file or timeout.
bool read_some(int fd, std::string& into, int ms) {
  pollfd p{fd, POLLIN, 0};
  if (::poll(&p, 1, ms) <= 0) return false;
  char buf[4096];
  const ssize_t n = ::read(fd, buf, sizeof buf);
  if (n <= 0) return false;
  into.append(buf, static_cast<size_t>(n));
  return true;
}

// The environment with `env`'s entries added or replacing ones of the same name.
std::vector<std::string> merged_environment(const std::vector<std::string>& env) {
  std::vector<std::string> out = env;
  for (char** e = environ; *e; ++e) {
    const std::string_view entry(*e);
    const auto name = entry.substr(0, entry.find('=') + 1);
    if (std::none_of(env.begin(), env.end(), [&](const std::string& x) { return x.starts_with(name); }))
      out.emplace_back(entry);
  }
  return out;
}

std::vector<char*> pointers(std::vector<std::string>& strings) {
  std::vector<char*> p;
  for (auto& s : strings) p.push_back(s.data());
  p.push_back(nullptr);
  return p;
}

}  // namespace

ListeningProcess::ListeningProcess(const std::vector<std::string>& argv_in,
                                   const std::vector<std::string>& env,
                                   const std::function<bool(const std::string&)>& ready) {
  static int counter = 0;
  const auto name = std::filesystem::path(argv_in.at(0)).filename().string();
  err_path_ = (std::filesystem::temp_directory_path() /
               (name + "_err_" + std::to_string(::getpid()) + "_" + std::to_string(counter++)))
                  .string();
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error("pipe failed");
  // Everything the child needs is made before fork: between fork and exec a
  // child of a threaded process may only make async-signal-safe calls (an
  // allocation there deadlocked under ASan).
  std::vector<std::string> argv_s = argv_in, env_s = merged_environment(env);
  const auto argv = pointers(argv_s), envp = pointers(env_s);
  pid_ = ::fork();
  if (pid_ == 0) {
    ::dup2(fds[1], 1);
    const int err = ::open(err_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(err, 2);
    ::close(fds[0]);
    ::execve(argv[0], argv.data(), envp.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  out_fd_ = fds[0];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!ready(out_)) {
    if (std::chrono::steady_clock::now() > deadline || !read_some(out_fd_, out_, 1000)) {
      if (std::chrono::steady_clock::now() > deadline || ::waitpid(pid_, nullptr, WNOHANG) != 0) {
        const int code = stop(SIGKILL);
        throw std::runtime_error(name + " did not announce itself (exit " + std::to_string(code) +
                                 "): " + err());
      }
    }
  }
}

ListeningProcess::~ListeningProcess() {
  if (pid_ > 0) stop(SIGKILL);
  if (out_fd_ >= 0) ::close(out_fd_);
  std::filesystem::remove(err_path_);
}

int ListeningProcess::stop(int signal) {
  if (pid_ <= 0) return -1;
  ::kill(pid_, signal);
  int status = 0;
  ::waitpid(pid_, &status, 0);
  pid_ = -1;
  while (read_some(out_fd_, out_, 100)) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string ListeningProcess::out() {
  while (read_some(out_fd_, out_, 0)) {
  }
  return out_;
}

std::string ListeningProcess::err() {
  std::ifstream in(err_path_);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace phasecast::testing
