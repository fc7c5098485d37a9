#pragma once
// What the seeded fuzzers share (docs/fuzzing.md): byte-level mutations drawn
// from one std::mt19937_64, so a run is reproducible from its seed; a crash
// and hang report naming the input being run; and the run's tallies.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <random>
#include <string>
#include <string_view>

namespace phasecast::fuzz {

using Bytes = std::string;

// Uniform draws from the run's one generator.
class Random {
 public:
  explicit Random(std::uint64_t seed) : rng_(seed) {}
  std::uint64_t below(std::uint64_t n) { return n == 0 ? 0 : rng_() % n; }  // [0, n)
  bool one_in(std::uint64_t n) { return below(n) == 0; }
  std::uint64_t bits() { return rng_(); }
  template <class T, std::size_t N>
  const T& pick(const T (&items)[N]) {
    return items[below(N)];
  }

 private:
  std::mt19937_64 rng_;
};

// Byte-level mutations. The in-place ones act on [lo, hi) only, so that a
// format-aware caller can aim them at one block (and repair its checksum).
class ByteMutator {
 public:
  explicit ByteMutator(Random& random) : random_(random) {}

  // One of the mutations below at random; `other` is a splice partner.
  void mutate(Bytes& data, const Bytes& other);
  // One in-place mutation inside [lo, hi): the size never changes.
  void mutate_in_place(Bytes& data, std::size_t lo, std::size_t hi);

  void flip_bit(Bytes& data, std::size_t lo, std::size_t hi);
  void set_byte(Bytes& data, std::size_t lo, std::size_t hi);     // an interesting byte value
  void set_word(Bytes& data, std::size_t lo, std::size_t hi);     // a 2/4/8-byte boundary value, LE or BE
  void add_to_byte(Bytes& data, std::size_t lo, std::size_t hi);  // +-1..16: counts, lengths, offsets
  void insert(Bytes& data);                                       // repeated or random bytes
  void erase(Bytes& data);
  void truncate(Bytes& data);
  void splice(Bytes& data, const Bytes& other);  // a piece of `other` over or into `data`

 private:
  Random& random_;
};

// A fatal signal (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT) while an input is
// running prints "<tool>: <signal> on input #N", the input in hex and a
// backtrace to stderr, saves the input to <dir>/crash-N.bin and dies; so does
// an input that runs longer than the watchdog (SIGALRM: a hang).
void install_crash_report(const char* tool, const std::filesystem::path& dir);

// Marks `bytes` as the input running for as long as it lives.
class RunningInput {
 public:
  RunningInput(std::uint64_t index, std::string_view bytes, unsigned watchdog_seconds);
  ~RunningInput();
  RunningInput(const RunningInput&) = delete;
  RunningInput& operator=(const RunningInput&) = delete;
};

// What a body run in a child process did: returned `result`, or died of a
// fatal signal or the watchdog: then `crash` is "<signal> in <innermost named
// function>" (e.g. "Floating point exception in H5D__chunk_set_info") and
// `backtrace` the child's.
struct Isolated {
  std::string result;
  std::string crash;
  std::string backtrace;
};

// Runs `body` in a forked child, so that a crash inside a library we call
// (libhdf5 on hostile files) is recorded and the run goes on.
Isolated run_isolated(const std::function<std::string()>& body, unsigned watchdog_seconds);

// Lower-case hex of `bytes`, at most `max` bytes of it ("..." after).
std::string hex(std::string_view bytes, std::size_t max = 4096);

// Writes `bytes` to `path` (throws std::runtime_error when it cannot).
void write_file(const std::filesystem::path& path, std::string_view bytes);
Bytes read_file(const std::filesystem::path& path);

// Counts per kind of outcome, for the summary and for novelty: an input whose
// outcome kind was never seen before joins the corpus.
class Tally {
 public:
  // Adds one outcome of `kind`; true if this kind is new.
  bool add(const std::string& kind) { return ++counts_[kind] == 1; }
  const std::map<std::string, std::uint64_t>& counts() const { return counts_; }
  // The `n` commonest kinds, one "  <count>  <kind>" line each.
  std::string commonest(std::size_t n) const;

 private:
  std::map<std::string, std::uint64_t> counts_;
};

// `text` with digit runs replaced by '#', quoted inputs by '*' and cut at
// `max` characters: the kind of an error line, without the numbers and names
// that differ between inputs.
std::string kind_of_line(std::string_view text, std::size_t max = 120);

}  // namespace phasecast::fuzz
