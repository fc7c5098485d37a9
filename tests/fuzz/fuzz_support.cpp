#include "fuzz_support.h"

#include <execinfo.h>
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <vector>

namespace phasecast::fuzz {
namespace {

// Values at the edges of the integer types, where size and index checks fail.
constexpr std::uint64_t kWords[] = {0,
                                    1,
                                    2,
                                    0x7f,
                                    0x80,
                                    0xff,
                                    0x100,
                                    0x7fff,
                                    0x8000,
                                    0xffff,
                                    0x10000,
                                    0x7fffffff,
                                    0x80000000,
                                    0xffffffff,
                                    0x100000000,
                                    std::uint64_t{1} << 40,
                                    std::uint64_t{1} << 61,
                                    0x7fffffffffffffff,
                                    0x8000000000000000,
                                    0xffffffffffffffff};
constexpr unsigned char kBytes[] = {0, 1, 2, 3, 4, 7, 8, 0x10, 0x20, 0x3f, 0x40, 0x7f, 0x80, 0xfe, 0xff};

}  // namespace

void ByteMutator::flip_bit(Bytes& data, std::size_t lo, std::size_t hi) {
  if (hi <= lo) return;
  data[lo + random_.below(hi - lo)] ^= static_cast<char>(1u << random_.below(8));
}

void ByteMutator::set_byte(Bytes& data, std::size_t lo, std::size_t hi) {
  if (hi <= lo) return;
  data[lo + random_.below(hi - lo)] = static_cast<char>(random_.pick(kBytes));
}

void ByteMutator::set_word(Bytes& data, std::size_t lo, std::size_t hi) {
  const std::size_t width = std::size_t{1} << random_.below(4);  // 1, 2, 4 or 8 bytes
  if (hi < lo + width) return;
  const std::size_t at = lo + random_.below(hi - lo - width + 1);
  const std::uint64_t value = random_.pick(kWords) - (random_.one_in(4) ? 1 : 0);
  const bool big_endian = random_.one_in(4);
  for (std::size_t i = 0; i < width; ++i) {
    const std::size_t shift = 8 * (big_endian ? width - 1 - i : i);
    data[at + i] = static_cast<char>((value >> shift) & 0xff);
  }
}

void ByteMutator::add_to_byte(Bytes& data, std::size_t lo, std::size_t hi) {
  if (hi <= lo) return;
  const auto delta = static_cast<int>(random_.below(16)) + 1;
  auto& b = data[lo + random_.below(hi - lo)];
  b = static_cast<char>(static_cast<unsigned char>(b) + (random_.one_in(2) ? delta : -delta));
}

void ByteMutator::insert(Bytes& data) {
  const std::size_t at = random_.below(data.size() + 1);
  const std::size_t n = 1 + random_.below(random_.one_in(8) ? 256 : 8);
  Bytes piece(n, static_cast<char>(random_.pick(kBytes)));
  if (random_.one_in(2)) {
    for (auto& c : piece) c = static_cast<char>(random_.bits());
  }
  data.insert(at, piece);
}

void ByteMutator::erase(Bytes& data) {
  if (data.empty()) return;
  const std::size_t at = random_.below(data.size());
  data.erase(at, 1 + random_.below(std::min<std::size_t>(data.size() - at, 16)));
}

void ByteMutator::truncate(Bytes& data) {
  data.resize(random_.below(data.size() + 1));
}

void ByteMutator::splice(Bytes& data, const Bytes& other) {
  if (other.empty()) return;
  const std::size_t from = random_.below(other.size());
  const std::size_t n = 1 + random_.below(other.size() - from);
  const std::size_t at = random_.below(data.size() + 1);
  if (random_.one_in(2)) {
    data.insert(at, other, from, n);
  } else {
    data.replace(at, std::min(n, data.size() - at), other, from, n);
  }
}

void ByteMutator::mutate_in_place(Bytes& data, std::size_t lo, std::size_t hi) {
  switch (random_.below(4)) {
    case 0:
      return flip_bit(data, lo, hi);
    case 1:
      return set_byte(data, lo, hi);
    case 2:
      return set_word(data, lo, hi);
    default:
      return add_to_byte(data, lo, hi);
  }
}

void ByteMutator::mutate(Bytes& data, const Bytes& other) {
  switch (random_.below(8)) {
    case 0:
      return insert(data);
    case 1:
      return erase(data);
    case 2:
      return truncate(data);
    case 3:
      return splice(data, other);
    default:
      return mutate_in_place(data, 0, data.size());
  }
}

// ---- crash and hang report --------------------------------------------------------
// The handler may only use async-signal-safe calls (write, open, _exit), so it
// reads plain globals set by RunningInput and formats numbers by hand.

namespace {

const char* g_tool = "fuzz";
int g_report_fd = 2;      // where a crash report goes: stderr, or the pipe of run_isolated()
bool g_isolated = false;  // in a run_isolated() child: report the signal and backtrace only
char g_dir[4096] = ".";
const char* g_bytes = nullptr;
std::size_t g_size = 0;
std::uint64_t g_index = 0;
volatile sig_atomic_t g_running = 0;

void put(int fd, const char* s) {
  if (::write(fd, s, std::strlen(s)) < 0) return;
}

// Decimal digits of `n` into `buf` (at least 21 chars); returns buf.
char* decimal(std::uint64_t n, char* buf) {
  char tmp[21];
  int len = 0;
  do {
    tmp[len++] = static_cast<char>('0' + n % 10);
    n /= 10;
  } while (n != 0);
  for (int i = 0; i < len; ++i) buf[i] = tmp[len - 1 - i];
  buf[len] = '\0';
  return buf;
}

void put_hex(int fd, const char* bytes, std::size_t n) {
  static const char digits[] = "0123456789abcdef";
  char line[129];
  for (std::size_t at = 0; at < n; at += 64) {
    std::size_t k = 0;
    for (std::size_t i = at; i < n && i < at + 64; ++i) {
      const auto b = static_cast<unsigned char>(bytes[i]);
      line[k++] = digits[b >> 4];
      line[k++] = digits[b & 15];
    }
    line[k] = '\0';
    put(fd, line);
    put(fd, "\n");
  }
}

void save_input(char* path) {
  const int fd = ::open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) return;
  if (::write(fd, g_bytes, g_size) < 0) put(2, "(could not save the input)\n");
  ::close(fd);
}

const char* signal_name(int sig) {
  return sig == SIGALRM ? "hang (watchdog)" : strsignal(sig);
}

void report_isolated(int sig) {
  put(g_report_fd, "C");
  put(g_report_fd, signal_name(sig));
  put(g_report_fd, "\n");
  void* frames[64];
  backtrace_symbols_fd(frames, backtrace(frames, 64), g_report_fd);
  ::_exit(128 + sig);
}

void on_fatal(int sig) {
  if (!g_running) {
    std::signal(sig, SIG_DFL);
    std::raise(sig);
    return;
  }
  if (g_isolated) report_isolated(sig);
  char number[21];
  put(2, "\n");
  put(2, g_tool);
  put(2, ": ");
  put(2, signal_name(sig));
  put(2, " on input #");
  put(2, decimal(g_index, number));
  put(2, " (");
  put(2, decimal(g_size, number));
  put(2, " bytes):\n");
  put_hex(2, g_bytes, g_size);
  char path[4200] = {};
  std::strcat(path, g_dir);
  std::strcat(path, "/crash-");
  std::strcat(path, decimal(g_index, number));
  std::strcat(path, ".bin");
  save_input(path);
  put(2, "saved to ");
  put(2, path);
  put(2, "\nbacktrace:\n");
  void* frames[64];
  backtrace_symbols_fd(frames, backtrace(frames, 64), 2);
  ::_exit(128 + sig);
}

}  // namespace

void install_crash_report(const char* tool, const std::filesystem::path& dir) {
  g_tool = tool;
  std::strncpy(g_dir, dir.c_str(), sizeof g_dir - 1);
  void* warm[1];
  backtrace(warm, 1);  // loads libgcc now: the first call may allocate
  struct sigaction action {};
  action.sa_handler = on_fatal;
  sigemptyset(&action.sa_mask);
  for (const int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGALRM}) sigaction(sig, &action, nullptr);
}

RunningInput::RunningInput(std::uint64_t index, std::string_view bytes, unsigned watchdog_seconds) {
  g_index = index;
  g_bytes = bytes.data();
  g_size = bytes.size();
  g_running = 1;
  ::alarm(watchdog_seconds);
}

RunningInput::~RunningInput() {
  ::alarm(0);
  g_running = 0;
}

namespace {

// The innermost frame of a backtrace_symbols_fd() listing that names a
// function, below the signal handler's frames (up to the libc trampoline).
std::string innermost_function(const std::string& backtrace) {
  const auto trampoline = backtrace.find("libc.so");
  std::size_t at = trampoline == std::string::npos ? 0 : backtrace.find('\n', trampoline);
  while (at != std::string::npos && at < backtrace.size()) {
    const auto end = backtrace.find('\n', at + 1);
    const std::string line =
        backtrace.substr(at + 1, end == std::string::npos ? std::string::npos : end - at - 1);
    const auto open = line.find('('), plus = line.find('+', open);
    if (open != std::string::npos && plus != std::string::npos && plus > open + 1) {
      return line.substr(open + 1, plus - open - 1);
    }
    at = end;
  }
  return "an unnamed function";
}

std::string read_all(int fd) {
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) out.append(buf, static_cast<std::size_t>(n));
  return out;
}

}  // namespace

Isolated run_isolated(const std::function<std::string()>& body, unsigned watchdog_seconds) {
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error("cannot create a pipe for an isolated run");
  const pid_t child = ::fork();
  if (child < 0) throw std::runtime_error("cannot fork an isolated run");
  if (child == 0) {
    ::close(fds[0]);
    g_report_fd = fds[1];
    g_isolated = true;
    g_running = 1;
    ::alarm(watchdog_seconds);
    const std::string result = "R" + body();
    if (::write(fds[1], result.data(), result.size()) < 0) ::_exit(3);
    ::_exit(0);
  }
  ::close(fds[1]);
  const std::string out = read_all(fds[0]);
  ::close(fds[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  Isolated r;
  if (out.starts_with("R") && WIFEXITED(status) && WEXITSTATUS(status) == 0) {
    r.result = out.substr(1);
  } else if (out.starts_with("C")) {
    const auto eol = out.find('\n');
    r.backtrace = out.substr(eol + 1);
    r.crash = out.substr(1, eol - 1) + " in " + innermost_function(r.backtrace);
  } else {
    r.crash = "child ended with status " + std::to_string(status) + " and no report";
  }
  return r;
}

// ---- files and text ---------------------------------------------------------------

std::string hex(std::string_view bytes, std::size_t max) {
  static const char digits[] = "0123456789abcdef";
  std::string out;
  for (std::size_t i = 0; i < bytes.size() && i < max; ++i) {
    const auto b = static_cast<unsigned char>(bytes[i]);
    out += digits[b >> 4];
    out += digits[b & 15];
  }
  if (bytes.size() > max) out += "...";
  return out;
}

void write_file(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out.flush()) throw std::runtime_error(path.string() + ": cannot write");
}

Bytes read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot read (expected a file)");
  return Bytes((std::istreambuf_iterator<char>(in)), {});
}

std::string Tally::commonest(std::size_t n) const {
  std::vector<std::pair<std::uint64_t, std::string>> kinds;
  for (const auto& [kind, count] : counts_) kinds.emplace_back(count, kind);
  std::sort(kinds.rbegin(), kinds.rend());
  std::string out;
  for (std::size_t i = 0; i < kinds.size() && i < n; ++i) {
    out += "  " + std::to_string(kinds[i].first) + "  " + kinds[i].second + "\n";
  }
  return out;
}

std::string kind_of_line(std::string_view text, std::size_t max) {
  // Echoed inputs are quoted, and may hold quotes themselves or be cut
  // short: everything from the first quote to the last "' (" is one '*'
  // (and all the rest, when there is no such closing quote).
  std::string squeezed(text);
  const auto first = text.find('\''), last = text.rfind("' (");
  if (first != std::string_view::npos) {
    squeezed.replace(first + 1,
                     last != std::string_view::npos && last > first ? last - first - 1 : std::string::npos,
                     "*");
  }
  std::string out;
  for (std::size_t i = 0; i < squeezed.size() && out.size() < max; ++i) {
    const char c = squeezed[i];
    if (c < '0' || c > '9') {
      out += c;
    } else if (out.empty() || out.back() != '#') {
      out += '#';
    }
  }
  return out;
}

}  // namespace phasecast::fuzz
