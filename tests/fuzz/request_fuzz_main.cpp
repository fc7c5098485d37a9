// phasecast-fuzz-requests: a seeded, deterministic mutation loop over
// SynthesisService::handle(bytes) with ticks interleaved (docs/fuzzing.md).
// The same --seed and --iterations replay the same inputs in the same order.

#include "request_harness.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>

namespace phasecast::fuzz {
namespace {

struct Options {
  std::vector<std::filesystem::path> packages;
  std::filesystem::path work_dir;
  std::uint64_t iterations = 20000;
  std::uint64_t seed = 1;
  std::uint64_t tick_one_in = 8;  // a tick after one input in this many
  std::filesystem::path replay;   // run this one input and stop
  std::string client;             // ... as sent by this client
  bool keep_going = false;
  bool strict = false;  // notes are violations too
};

struct Run {
  Tally tally;
  Tally notes;
  std::uint64_t violations = 0;
  std::uint64_t ticks = 0;
};

constexpr std::size_t kCorpusLimit = 4096;
constexpr unsigned kWatchdogSeconds = 20;

// Reports a broken invariant; true when the run should stop.
bool report(const Options& o, Run& run, std::uint64_t index, std::string_view bytes,
            const std::string& what) {
  ++run.violations;
  const auto saved = o.work_dir / fmt::format("violation-{}.bin", index);
  write_file(saved, bytes);
  std::cerr << fmt::format(
      "phasecast-fuzz-requests: input #{} (seed {}): {}\n  {} bytes: {}\n  saved to {}\n", index, o.seed,
      what, bytes.size(), hex(bytes, 512), saved.string());
  return !o.keep_going;
}

// A note is printed the first time its kind is seen, then counted.
bool note(const Options& o, Run& run, std::uint64_t index, std::string_view bytes, const std::string& what) {
  if (o.strict) return report(o, run, index, bytes, what);
  if (run.notes.add(what)) {
    std::cerr << fmt::format("phasecast-fuzz-requests: note: input #{} (seed {}): {}\n  {} bytes: {}\n",
                             index, o.seed, what, bytes.size(), hex(bytes, 512));
  }
  return false;
}

int replay(const Options& o, RequestHarness& harness) {
  const Bytes bytes = read_file(o.replay);
  const RunningInput running(0, bytes, kWatchdogSeconds);
  const auto v = harness.run(bytes, o.client);
  std::cout << fmt::format("{}: {}{}{}\n", o.replay.string(), v.kind,
                           v.violation.empty() ? "" : ": " + v.violation,
                           v.note.empty() ? "" : " (note: " + v.note + ")");
  return v.violation.empty() ? 0 : 1;
}

void summarize(const Options& o, const Run& run, const RequestHarness& harness, std::uint64_t inputs,
               std::size_t corpus, double seconds) {
  std::cout << fmt::format(
      "phasecast-fuzz-requests: {} inputs, {} ticks, seed {}, {:.1f} s ({:.0f} inputs/s), corpus {}, "
      "{} reply kinds, {} violations\n",
      inputs, run.ticks, o.seed, seconds, static_cast<double>(inputs) / std::max(seconds, 1e-9), corpus,
      run.tally.counts().size(), run.violations);
  std::uint64_t ok = 0;
  for (const auto& [kind, n] : run.tally.counts()) ok += kind.starts_with("ok ") ? n : 0;
  std::cout << fmt::format("  {}\n  {} ok replies, {} error replies; the commonest kinds:\n",
                           harness.activity(), ok, inputs - ok);
  std::cout << run.tally.commonest(15);
  if (!run.notes.counts().empty())
    std::cout << "  notes (--strict makes them violations):\n" << run.notes.commonest(10);
}

int fuzz(const Options& o) {
  std::filesystem::create_directories(o.work_dir);
  install_crash_report("phasecast-fuzz-requests", o.work_dir);
  RequestHarness harness(o.packages, o.work_dir);
  if (!o.replay.empty()) return replay(o, harness);
  Random random(o.seed);
  RequestMutator mutator(random, harness);
  std::vector<Bytes> corpus = harness.seeds();
  const std::size_t seeds = corpus.size();
  Run run;
  const auto start = std::chrono::steady_clock::now();
  std::uint64_t i = 0;
  for (; i < o.iterations; ++i) {
    // The seeds go in unchanged first: every kind of request is answered once as is.
    const Bytes bytes =
        i < seeds ? corpus[i]
                  : mutator.mutate(corpus[random.below(corpus.size())], corpus[random.below(corpus.size())]);
    // Half the inputs come from one of two named clients (per-client limits).
    static const std::string kClients[] = {"", "", "alice", "bob"};
    const std::string& client = random.pick(kClients);
    RequestVerdict v;
    {
      const RunningInput running(i, bytes, kWatchdogSeconds);
      v = harness.run(bytes, client);
    }
    const std::string from = client.empty() ? "" : " (from client " + client + ")";
    if (!v.violation.empty() && report(o, run, i, bytes, v.violation + from)) break;
    if (!v.note.empty() && note(o, run, i, bytes, v.note)) break;
    if (run.tally.add(v.kind) && corpus.size() < kCorpusLimit) corpus.push_back(bytes);
    if (auto t = harness.top_up(); !t.empty() && report(o, run, i, bytes, t)) break;
    if (random.one_in(o.tick_one_in)) {
      ++run.ticks;
      if (auto t = harness.tick(); !t.empty() && report(o, run, i, bytes, "after this input: " + t)) break;
    }
    if (i % 4096 == 4095) {
      if (auto t = harness.tidy(); !t.empty() && report(o, run, i, bytes, t)) break;
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  summarize(o, run, harness, std::min(i + 1, o.iterations), corpus.size(), seconds);
  harness.tidy();
  return run.violations == 0 ? 0 : 1;
}

}  // namespace
}  // namespace phasecast::fuzz

int main(int argc, char** argv) {
  using phasecast::fuzz::Options;
  Options o;
  CLI::App app{
      "Feeds mutated phasecast.v1.Request bytes to SynthesisService::handle() and checks that each gets "
      "exactly one well-formed reply and that nothing throws, crashes or hangs (docs/fuzzing.md)."};
  app.add_option("--package", o.packages, "tiny packages to serve (e.g. tests/data/packages/plant_pot.h5)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--work-dir", o.work_dir, "where recordings, violations and crash inputs go")->required();
  app.add_option("--iterations", o.iterations, "inputs to run")->capture_default_str();
  app.add_option("--seed", o.seed, "seed of the mutation generator")->capture_default_str();
  app.add_option("--tick-one-in", o.tick_one_in, "tick after one input in this many")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--replay", o.replay, "run this one saved input and stop")->check(CLI::ExistingFile);
  app.add_option("--client", o.client, "with --replay: the client that sent it (see the report)");
  app.add_flag("--keep-going", o.keep_going, "count violations instead of stopping at the first");
  app.add_flag("--strict", o.strict, "treat notes (e.g. an error reply of several lines) as violations");
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-fuzz-requests"))
    return *status;
  try {
    return phasecast::fuzz::fuzz(o);
  } catch (const std::exception& e) {
    std::cerr << "phasecast-fuzz-requests: " << e.what() << "\n";
    return 2;
  }
}
