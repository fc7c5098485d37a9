// phasecast-fuzz-package: a seeded, deterministic mutation loop over package
// files read by core::read_package (docs/fuzzing.md). The seeds are two tiny
// synthetic packages (with and without appearance) and any --package given.

#include "package_harness.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <iostream>

namespace phasecast::fuzz {
namespace {

struct Options {
  std::vector<std::filesystem::path> packages;
  std::filesystem::path work_dir;
  std::uint64_t iterations = 300;
  std::uint64_t seed = 1;
  std::filesystem::path replay;
  bool keep_going = false;
  bool in_process = false;  // no child process per input: a crash ends the run
};

constexpr std::size_t kCorpusLimit = 512;
constexpr unsigned kWatchdogSeconds = 30;

// Small enough that most of the file is metadata, which is where mutations
// reach the reader's checks rather than only Fletcher-32.
std::vector<Bytes> synthetic_seeds(const std::filesystem::path& dir) {
  std::vector<Bytes> out;
  for (const bool appearance : {true, false}) {
    testing::PlateOptions p;
    p.grid = 3;
    p.rank_u = 2;
    p.irfs_per_entry = 1;
    p.irf_length = 6;
    p.clusters = 3;
    p.appearance = appearance;
    const auto path = dir / fmt::format("seed-{}.h5", appearance ? "appearance" : "plain");
    core::write_package(testing::make_plate_package(p), path);
    out.push_back(read_file(path));
  }
  return out;
}

struct Run {
  Tally tally;
  std::uint64_t violations = 0;
  std::uint64_t accepted = 0;
};

bool report(const Options& o, Run& run, std::uint64_t index, const Bytes& bytes, const std::string& what) {
  ++run.violations;
  const auto saved = o.work_dir / fmt::format("violation-{}.h5", index);
  write_file(saved, bytes);
  std::cerr << fmt::format("phasecast-fuzz-package: input #{} (seed {}): {}\n  saved to {}\n", index, o.seed,
                           what, saved.string());
  return !o.keep_going;
}

void summarize(const Options& o, const Run& run, std::uint64_t inputs, std::size_t corpus, double seconds) {
  std::cout << fmt::format(
      "phasecast-fuzz-package: {} inputs, seed {}, {:.1f} s ({:.0f} inputs/s), corpus {}, {} accepted, "
      "{} kinds of refusal, {} violations\n",
      inputs, o.seed, seconds, static_cast<double>(inputs) / std::max(seconds, 1e-9), corpus, run.accepted,
      run.tally.counts().size() - (run.accepted ? 1 : 0), run.violations);
  std::cout << run.tally.commonest(12);  // which checks the mutations reach
  // Crashes inside libhdf5 that read_package's child process contained.
  for (const auto& [kind, n] : run.tally.counts()) {
    if (kind.find("crashed the checking process") != std::string::npos)
      std::cout << fmt::format("  contained: {} x {}\n", n, kind);
  }
}

// One input, in a child process unless --in-process: a crash inside libhdf5
// becomes the verdict "crash <signal> in <function>" and the run goes on.
PackageVerdict run_one(const Options& o, PackageHarness& harness, std::uint64_t index, const Bytes& bytes) {
  if (o.in_process) {
    const RunningInput running(index, bytes, kWatchdogSeconds);
    return harness.run(bytes);
  }
  const Isolated r = run_isolated(
      [&] {
        const auto v = harness.run(bytes);
        return v.kind + '\n' + v.violation;
      },
      kWatchdogSeconds);
  if (!r.crash.empty()) {
    return {.violation = fmt::format("{}; backtrace:\n{}", r.crash, r.backtrace), .kind = "crash " + r.crash};
  }
  const auto eol = r.result.find('\n');
  return {.violation = r.result.substr(eol + 1), .kind = r.result.substr(0, eol)};
}

int fuzz(const Options& o) {
  std::filesystem::create_directories(o.work_dir);
  install_crash_report("phasecast-fuzz-package", o.work_dir);
  PackageHarness harness(o.work_dir / "input.h5");
  if (!o.replay.empty()) {
    const auto v = run_one(o, harness, 0, read_file(o.replay));
    std::cout << fmt::format("{}: {}{}\n", o.replay.string(), v.kind,
                             v.violation.empty() ? "" : ": " + v.violation);
    return v.violation.empty() ? 0 : 1;
  }
  std::vector<Bytes> corpus = synthetic_seeds(o.work_dir);
  for (const auto& p : o.packages) corpus.push_back(read_file(p));
  const std::size_t seeds = corpus.size();
  Random random(o.seed);
  PackageMutator mutator(random);
  Run run;
  const auto start = std::chrono::steady_clock::now();
  std::uint64_t i = 0;
  for (; i < o.iterations; ++i) {
    const Bytes bytes =
        i < seeds ? corpus[i]
                  : mutator.mutate(corpus[random.below(corpus.size())], corpus[random.below(seeds)]);
    PackageVerdict v = run_one(o, harness, i, bytes);
    if (i < seeds && v.kind != "accepted") v.violation = "seed package refused: " + v.kind;
    const bool novel = run.tally.add(v.kind);
    run.accepted += v.kind == "accepted" ? 1 : 0;
    if (!v.violation.empty()) {
      // A crash is reported in full the first time its site is seen, then counted.
      if (!v.kind.starts_with("crash ") || novel) {
        if (report(o, run, i, bytes, v.violation)) break;
      } else {
        ++run.violations;
      }
      continue;  // a crashing input is no parent: its children would mostly crash alike
    }
    if (novel && corpus.size() < kCorpusLimit) corpus.push_back(bytes);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  summarize(o, run, std::min(i + 1, o.iterations), corpus.size(), seconds);
  return run.violations == 0 ? 0 : 1;
}

}  // namespace
}  // namespace phasecast::fuzz

int main(int argc, char** argv) {
  phasecast::fuzz::Options o;
  CLI::App app{
      "Reads mutated package files with core::read_package and checks that each is either a valid, servable "
      "package or one core::PackageError line, never another exception, a crash or a hang "
      "(docs/fuzzing.md)."};
  app.add_option("--package", o.packages, "more seed packages (e.g. tests/data/packages/plant_pot.h5)")
      ->check(CLI::ExistingFile);
  app.add_option("--work-dir", o.work_dir, "where inputs, violations and crash inputs go")->required();
  app.add_option("--iterations", o.iterations, "inputs to run")->capture_default_str();
  app.add_option("--seed", o.seed, "seed of the mutation generator")->capture_default_str();
  app.add_option("--replay", o.replay, "read this one saved input and stop")->check(CLI::ExistingFile);
  app.add_flag("--keep-going", o.keep_going, "count violations instead of stopping at the first");
  app.add_flag("--in-process", o.in_process, "read each input in this process, not a child (for a debugger)");
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-fuzz-package"))
    return *status;
  try {
    return phasecast::fuzz::fuzz(o);
  } catch (const std::exception& e) {
    std::cerr << "phasecast-fuzz-package: " << e.what() << "\n";
    return 2;
  }
}
