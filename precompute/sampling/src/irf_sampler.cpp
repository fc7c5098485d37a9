#include "phasecast/precompute/sampling/irf_sampler.h"

#include "phasecast/precompute/sampling/orbit_recorder.h"

#include "phasecast/core/hdf5_file.h"

#include <fmt/format.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace phasecast::precompute {
namespace {

namespace h5 = core::h5;

// SplitMix64: decorrelates (seed, chain, irf) into independent random words.
std::uint64_t splitmix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// Frame chunks of the merged store, which the reduction reads in blocks of
// frames on each SVD pass: 1-frame chunks (the chain stores' for the cloth
// door) made its reduce 30 % slower than 64 KiB ones, which cost an append
// at most 64 KiB per frame dataset to rewrite.
constexpr std::uint64_t kMergedChunkBytes = std::uint64_t{64} << 10;

std::filesystem::path chain_store(const std::filesystem::path& dir, int chain) {
  return chain_store_path(dir, chain);
}

std::filesystem::path chain_state(const std::filesystem::path& dir, int chain) {
  return dir / fmt::format("chain-{:03d}.state.h5", chain);
}

// The exact (double) simulator state after a chain's last checkpointed IRF.
struct Checkpoint {
  int irfs = 0;
  int previous = -1;
  std::string lead_in;  // lead_in_key's: a checkpoint of another lead-in is another chain
  SimState state;
};

// The chain's lead-in as text ("recorded 2: entry seconds; ..."; empty from
// rest). An adaptive round's chain k depends on the segment it is directed
// at, which the options before the round decide, not the seed alone, and on
// how many of its items are recorded (a checkpoint of one recorded item is
// another chain's).
std::string lead_in_key(const SamplingOptions& o, int chain) {
  const auto k = static_cast<size_t>(chain);
  if (k >= o.lead_ins.size() || o.lead_ins[k].empty()) return {};
  std::string key = fmt::format("recorded {}: ", kRecordedLeadIns);
  const char* separator = "";
  for (const ScheduleItem& item : o.lead_ins[k]) {
    key += fmt::format("{}{} {:.17g}", separator, item.entry, item.duration);
    separator = "; ";
  }
  return key;
}

void write_checkpoint(const std::filesystem::path& path, const Checkpoint& c, const SamplingOptions& o,
                      int chain) {
  try {
    h5::write_atomically(path, [&c, &o, chain](h5::File& f) {
      f.write_attribute("seed", std::to_string(o.seed));
      f.write_attribute("chain", std::int32_t{chain});
      f.write_attribute("irfs", std::int32_t{c.irfs});
      f.write_attribute("previous", std::int32_t{c.previous});
      f.write_attribute("lead_in", lead_in_key(o, chain));
      f.write_attribute("time", c.state.time);
      f.write("/x", c.state.x);
      f.write("/v", c.state.v);
      const auto& s = c.state.support;
      Eigen::VectorXd support(10);
      support << s.held, s.pulse, s.pulse_time, s.coordinate;
      f.write("/support", support);
    });
  } catch (const h5::Failure& e) {
    throw SamplingError(fmt::format("{}: cannot write the checkpoint: {}", path.string(), e.what()));
  }
}

Checkpoint read_checkpoint(const std::filesystem::path& path, const SamplingOptions& o, int chain,
                           Eigen::Index n) {
  const std::string src = path.string();
  try {
    const h5::File f = h5::File::open_read(path);
    const h5::Reader r = h5::checked_reader<SamplingError>(f, src);
    if (f.read_attribute_string("seed") != std::to_string(o.seed) ||
        static_cast<int>(f.read_attribute_number("chain")) != chain) {
      throw SamplingError(
          fmt::format("{}: checkpoint of seed {} chain {}, expected seed {} chain {} (--resume with "
                      "the same --seed)",
                      src, f.read_attribute_string("seed"), f.read_attribute_number("chain"), o.seed, chain));
    }
    Checkpoint c;
    c.irfs = static_cast<int>(f.read_attribute_number("irfs"));
    c.previous = static_cast<int>(f.read_attribute_number("previous"));
    if (f.has_attribute("lead_in")) c.lead_in = f.read_attribute_string("lead_in");
    c.state.time = f.read_attribute_number("time");
    c.state.x = r.column<double>("/x", n);
    c.state.v = r.column<double>("/v", n);
    const Eigen::VectorXd s = r.column<double>("/support", 10);
    c.state.support.held = s.segment<3>(0);
    c.state.support.pulse = s.segment<3>(3);
    c.state.support.pulse_time = s(6);
    c.state.support.coordinate = s.segment<3>(7);
    return c;
  } catch (const h5::Failure& e) {
    throw SamplingError(fmt::format("{}: unreadable checkpoint: {}", src, e.what()));
  }
}

struct Shared {
  std::mutex mutex;
  SamplingProgress progress;
  std::atomic<int> new_irfs{0};
  std::atomic<bool> stop{false};
};

// The chain's store, ready for its next IRF: continued after the checkpoint
// when resuming (`c` and `sim` then hold the checkpointed state), else new.
// A store that cannot be continued (a crash tore the file) is sampled again:
// a chain is a pure function of the seed and its lead-in, so nothing changes
// but the time.
OrbitStoreAppender open_chain(const Scene& scene, const SamplingOptions& o, int chain, Checkpoint& c,
                              Simulator& sim, Shared& sh) {
  const auto store_path = chain_store(o.work_dir, chain), state_path = chain_state(o.work_dir, chain);
  const bool checkpointed = std::filesystem::exists(store_path) && std::filesystem::exists(state_path);
  const auto saved_if_same_chain = [&]() -> std::optional<Checkpoint> {
    if (!o.resume || !checkpointed) return std::nullopt;
    Checkpoint saved = read_checkpoint(state_path, o, chain, 3 * static_cast<Eigen::Index>(sim.vertices()));
    if (saved.lead_in == lead_in_key(o, chain)) return saved;
    std::lock_guard lock(sh.mutex);
    if (o.notice)
      o.notice(
          fmt::format("chain {}: its checkpoint was led in by another guide segment (options changed "
                      "since the interrupted run); sampling the chain again",
                      chain));
    return std::nullopt;
  };
  const std::optional<Checkpoint> saved = saved_if_same_chain();
  if (saved && !sim.restores_any_state()) {
    // A finished chain is kept; an unfinished one cannot be continued by its simulator.
    if (saved->irfs == o.irfs_per_chain) {
      try {
        OrbitStoreAppender store = OrbitStoreAppender::reopen(store_path, saved->irfs);
        c = *saved;
        return store;
      } catch (const OrbitStoreError&) {  // a torn store: the chain is sampled again below
      }
    }
    std::lock_guard lock(sh.mutex);
    if (o.notice)
      o.notice(fmt::format("chain {}: its simulator cannot continue a checkpoint; sampling the chain again",
                           chain));
  } else if (saved) {
    if (saved->irfs > o.irfs_per_chain) {
      throw SamplingError(fmt::format("{}: checkpoint holds {} IRFs, more than --irfs-per-chain {}",
                                      state_path.string(), saved->irfs, o.irfs_per_chain));
    }
    try {
      OrbitStoreAppender store = OrbitStoreAppender::reopen(store_path, saved->irfs);
      c = *saved;
      sim.reset(c.state);
      return store;
    } catch (const OrbitStoreError& e) {
      std::lock_guard lock(sh.mutex);
      if (o.notice)
        o.notice(fmt::format("chain {}: {}; sampling the chain again from its start", chain, e.what()));
    }
  }
  // The stale state goes first: a crash before this chain's first checkpoint
  // must not pair an old state with the new store.
  std::error_code ignored;
  std::filesystem::remove(state_path, ignored);
  return OrbitStoreAppender::create(store_path, empty_orbit_store(scene));
}

// Where a chain stands after its first `irfs` IRFs: its history and the
// support coordinate, by replaying the draws. They must reproduce the
// checkpointed entries and lengths (else the scene's rules changed).
struct ChainPosition {
  std::vector<int> history;
  double at = 0;
};

// Frames of a lead-in item started at support coordinate `at`: its
// duration, clipped to the support's range like a drawn IRF's.
int lead_in_frames(const PaletteRules& rules, const ScheduleItem& item, double frame_dt, double at) {
  return std::max(1,
                  std::min(schedule_frames(item.duration, frame_dt), rules.reachable_frames(item.entry, at)));
}

// The index of chain `chain`'s first recorded lead-in item. The segment is the
// lead-in's last item; the item before it is recorded too, so the segment's
// IRF continues a stored one and its start keeps the velocity the impulse
// finds (eq. 8, and the IRF cache's support velocity). Earlier items are
// simulated only.
size_t first_recorded_lead_in(const SamplingOptions& o, int chain) {
  const auto k = static_cast<size_t>(chain);
  if (k >= o.lead_ins.size()) return 0;
  return o.lead_ins[k].size() > kRecordedLeadIns ? o.lead_ins[k].size() - kRecordedLeadIns : 0;
}

// Walks chain `chain`'s lead-in up to its recorded items (simulated, not
// recorded), calling visit(item, frames) for each; returns where the chain's
// first IRF starts (at rest when it has no lead-in).
template <class Visit>
ChainPosition walk_lead_in(const PaletteRules& rules, const SamplingOptions& o, double frame_dt, int chain,
                           Visit visit) {
  ChainPosition p;
  const auto k = static_cast<size_t>(chain);
  if (k >= o.lead_ins.size()) return p;
  for (size_t i = 0; i < first_recorded_lead_in(o, chain); ++i) {
    const ScheduleItem& item = o.lead_ins[k][i];
    const int frames = lead_in_frames(rules, item, frame_dt, p.at);
    visit(item, frames);
    p.history.push_back(item.entry);
    p.at = rules.advance(item.entry, p.at, frames);
  }
  return p;
}

ChainPosition replay_chain(const PaletteRules& rules, const SamplingOptions& o, double frame_dt, int chain,
                           const IrfList& store, int irfs) {
  ChainPosition p = walk_lead_in(rules, o, frame_dt, chain, [](const ScheduleItem&, int) {});
  for (int i = 0; i < irfs; ++i) {
    const IrfDraw d = next_irf(rules, o, frame_dt, chain, i, p.history, p.at);
    const auto k = static_cast<size_t>(i);
    if (d.entry != store.palette[k] || d.frames != store.length[k]) {
      throw SamplingError(fmt::format(
          "{}: checkpointed IRF {} is entry {} for {} frames but the palette rules now draw {} for {} (was "
          "the scene changed?)",
          chain_store(o.work_dir, chain).string(), i, store.palette[k], store.length[k], d.entry, d.frames));
    }
    if (d.from_rest) p.history.clear(), p.at = 0;
    p.history.push_back(d.entry);
    p.at = rules.advance(d.entry, p.at, d.frames);
  }
  return p;
}

// A directed chain's lead-in up to its recorded items, simulated from rest and
// not recorded: the chain's first IRF starts where the schedule it comes from
// stood (the checkpoints then hold the state past it).
void play_lead_in(Simulator& sim, const Scene& scene, const PaletteRules& rules, const SamplingOptions& o,
                  int chain, IrfFrames& scratch) {
  walk_lead_in(rules, o, scene.simulation.frame_dt, chain, [&](const ScheduleItem& item, int frames) {
    record_irf_frames(sim, scene, item.entry, frames, true, scratch);
  });
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Runs (or resumes) one chain; returns the IRFs its store holds.
int run_chain(const Scene& scene, const PaletteRules& rules, const SamplingOptions& o, int chain,
              Shared& sh) {
  const auto start = std::chrono::steady_clock::now();
  auto sim = make_simulator(scene);
  // Chains start from the settled rest, as simulate_schedule (the truth the
  // validator compares with) and the server's rest node do.
  const SimState rest = settled_rest_state(scene, *sim);
  const double settle_seconds = seconds_since(start);
  Checkpoint c;
  c.state = rest;
  sim->reset(c.state);
  OrbitStoreAppender store = open_chain(scene, o, chain, c, *sim, sh);
  {
    std::lock_guard lock(sh.mutex);
    sh.progress.irfs_done += c.irfs;
    sh.progress.nodes += store.frames();
    if (o.progress) o.progress(sh.progress);
  }
  ChainPosition at = replay_chain(rules, o, scene.simulation.frame_dt, chain, store.irf_table(), c.irfs);
  IrfFrames irf;  // the only frames a chain holds: the IRF being recorded
  if (c.irfs == 0) play_lead_in(*sim, scene, rules, o, chain, irf);
  const int resumed_irfs = c.irfs;
  const std::int64_t resumed_frames = store.frames();
  for (int i = c.irfs; i < o.irfs_per_chain; ++i) {
    if (sh.stop) break;
    const IrfDraw draw = next_irf(rules, o, scene.simulation.frame_dt, chain, i, at.history, at.at);
    if (draw.from_rest) {
      sim->reset(rest);
      at = ChainPosition{};
    }
    at.history.push_back(draw.entry);
    record_irf_frames(*sim, scene, draw.entry, draw.frames, !draw.from_rest, irf);
    at.at = rules.advance(draw.entry, at.at, draw.frames);
    c.irfs = i + 1;
    c.previous = draw.entry;
    c.state = sim->state();
    // Store first, then state: a crash in between leaves one extra IRF that resume drops.
    store.append(irf);
    write_checkpoint(chain_state(o.work_dir, chain), c, o, chain);
    std::lock_guard lock(sh.mutex);
    sh.progress.irfs_done += 1;
    sh.progress.nodes += draw.frames;
    if (o.progress) o.progress(sh.progress);
    if (o.stop_after_irfs > 0 && ++sh.new_irfs >= o.stop_after_irfs) sh.stop = true;
  }
  // The time of one chain is what a run spread over many ranks costs per chain (docs/distributed.md).
  const auto frames = store.frames() - resumed_frames;
  if (o.chain_sampled && store.irfs() == o.irfs_per_chain && frames > 0) {
    o.chain_sampled({chain, store.irfs() - resumed_irfs, frames, seconds_since(start), settle_seconds});
  }
  return store.irfs();
}

}  // namespace

std::filesystem::path chain_store_path(const std::filesystem::path& work_dir, int chain) {
  return work_dir / fmt::format("chain-{:03d}.h5", chain);
}

IrfDraw draw_irf(const PaletteRules& rules, std::uint64_t seed, int chain, int irf,
                 const std::vector<int>& history, double at) {
  std::uint64_t word = splitmix(splitmix(splitmix(seed) ^ static_cast<std::uint64_t>(chain)) ^
                                static_cast<std::uint64_t>(irf));
  IrfDraw d;
  const int previous = history.empty() ? -1 : history.back();
  const int follow_up = previous >= 0 ? rules.on_end[static_cast<size_t>(previous)] : core::kEndRest;
  if (follow_up >= 0 && rules.allowed_at(history, follow_up, at)) {
    d.entry = follow_up;  // the named follow-up
  } else {
    std::vector<int> next;
    for (int e = 0; e < rules.size(); ++e) {
      if (rules.allowed_at(history, e, at)) next.push_back(e);
    }
    if (next.empty()) {  // nothing may follow: back to rest
      d.from_rest = true;
      at = 0;
      for (int e : rules.successors(-1)) {
        if (rules.reachable_frames(e, at) >= 1) next.push_back(e);
      }
      if (next.empty())
        throw SamplingError("palette rules: no entry may start from rest (add \"rest\" to an 'after')");
    }
    d.entry = next[word % next.size()];
  }
  word = splitmix(word);
  const auto e = static_cast<size_t>(d.entry);
  const int longest = rules.reachable_frames(d.entry, at);
  const int shortest = std::min(rules.min_frames[e], longest);
  d.frames = shortest + static_cast<int>(word % static_cast<std::uint64_t>(longest - shortest + 1));
  return d;
}

IrfDraw next_irf(const PaletteRules& rules, const SamplingOptions& o, double frame_dt, int chain, int irf,
                 const std::vector<int>& history, double at) {
  const auto k = static_cast<size_t>(chain);
  const size_t item = first_recorded_lead_in(o, chain) + static_cast<size_t>(irf);
  if (k >= o.lead_ins.size() || item >= o.lead_ins[k].size())
    return draw_irf(rules, o.seed, chain, irf, history, at);
  IrfDraw d;
  d.entry = o.lead_ins[k][item].entry;
  d.frames = lead_in_frames(rules, o.lead_ins[k][item], frame_dt, at);
  return d;
}

void check_sampling_options(const SamplingOptions& o) {
  if (o.chains < 1 || o.irfs_per_chain < 1 || o.jobs < 1)
    throw SamplingError(fmt::format("sampling: expected chains, IRFs per chain and jobs >= 1, got {}, {}, {}",
                                    o.chains, o.irfs_per_chain, o.jobs));
  if (o.ranks < 1 || o.rank < 0 || o.rank >= o.ranks)
    throw SamplingError(fmt::format("sampling: rank {} of {} (expected 0 <= rank < ranks)", o.rank, o.ranks));
  for (size_t k = 0; k < o.lead_ins.size() && k < static_cast<size_t>(o.chains); ++k) {
    const size_t recorded = std::min(kRecordedLeadIns, o.lead_ins[k].size());
    if (static_cast<size_t>(o.irfs_per_chain) < recorded)  // the segment's IRF would never be recorded
      throw SamplingError(
          fmt::format("sampling: chain {}'s lead-in records {} IRFs, expected IRFs per chain >= {}, got {}",
                      k, recorded, recorded, o.irfs_per_chain));
  }
}

namespace {

void make_work_dir(const SamplingOptions& o) {
  std::error_code error;
  std::filesystem::create_directories(o.work_dir, error);
  if (error || !std::filesystem::is_directory(o.work_dir)) {
    throw SamplingError(fmt::format("work folder {}: cannot create it ({})", o.work_dir.string(),
                                    error ? error.message() : "not a folder"));
  }
}

int own_chains(const SamplingOptions& o) {
  int n = 0;
  for (int k = o.rank; k < o.chains; k += o.ranks) ++n;
  return n;
}

// This rank's chains (k = rank, rank + ranks, ...) on `jobs` threads, each
// left complete in its store; SamplingError if any stopped short.
void run_own_chains(const Scene& scene, const PaletteRules& rules, const SamplingOptions& o) {
  check_sampling_options(o);
  make_work_dir(o);
  Shared sh;
  sh.progress.irfs_total = own_chains(o) * o.irfs_per_chain;
  std::vector<int> irfs(static_cast<size_t>(o.chains), 0);
  std::vector<std::string> errors(static_cast<size_t>(o.chains));
  std::atomic<int> next{0};
  const auto worker = [&] {
    for (int i = next++, k = o.rank + i * o.ranks; k < o.chains; i = next++, k = o.rank + i * o.ranks) {
      try {
        irfs[static_cast<size_t>(k)] = run_chain(scene, rules, o, k, sh);
      } catch (const std::exception& e) {
        errors[static_cast<size_t>(k)] = fmt::format("chain {}: {}", k, e.what());
        sh.stop = true;
      }
    }
  };
  std::vector<std::thread> threads;
  for (int j = 0; j < std::min(o.jobs, std::max(1, own_chains(o))); ++j) threads.emplace_back(worker);
  for (auto& t : threads) t.join();
  for (const auto& e : errors) {
    if (!e.empty()) throw SamplingError(e);
  }
  for (int k = o.rank; k < o.chains; k += o.ranks) {
    if (irfs[static_cast<size_t>(k)] != o.irfs_per_chain) {
      throw SamplingError(fmt::format(
          "sampling stopped after {} new IRFs (--stop-after-irfs); rerun with --resume", sh.new_irfs.load()));
    }
  }
}

// Checks that every chain's store exists, holds all its IRFs and belongs to
// the scene; returns the frames of them all.
long long check_chain_stores(const Scene& scene, const SamplingOptions& o) {
  long long frames = 0;
  for (int k = 0; k < o.chains; ++k) {
    const auto path = chain_store(o.work_dir, k);
    if (!std::filesystem::exists(path)) {
      throw SamplingError(fmt::format(
          "{}: chain {} has no store (expected every rank to share the work folder; docs/distributed.md)",
          path.string(), k));
    }
    const OrbitStoreReader c(path);
    if (static_cast<int>(c.irfs().size()) != o.irfs_per_chain) {
      throw SamplingError(fmt::format("{}: chain {} holds {} IRFs (expected {}; rerun with --resume)",
                                      path.string(), k, c.irfs().size(), o.irfs_per_chain));
    }
    if (c.header().vertices() != scene.model.vertices()) {
      throw SamplingError(fmt::format("{}: chain {} has {} vertices, expected the {} of scene '{}'",
                                      path.string(), k, c.header().vertices(), scene.model.vertices(),
                                      scene.name));
    }
    for (const std::int32_t n : c.irfs().length) frames += n;
  }
  return frames;
}

// Calls `take` with every IRF of every chain, in chain order, one at a time.
void for_each_chain_irf(const SamplingOptions& o, const std::function<void(const IrfFrames&)>& take) {
  IrfFrames irf;
  for (int k = 0; k < o.chains; ++k) {
    const OrbitStoreReader c(chain_store(o.work_dir, k));
    for (int i = 0; i < static_cast<int>(c.irfs().size()); ++i) {
      c.read(i, irf);
      take(irf);
    }
  }
}

}  // namespace

void sample_own_chains(const Scene& scene, const PaletteRules& rules, const SamplingOptions& o) {
  run_own_chains(scene, rules, o);
}

OrbitStore sample_irfs(const Scene& scene, const PaletteRules& rules, const SamplingOptions& o) {
  if (o.ranks != 1) throw SamplingError("sample_irfs runs every chain: use sample_own_chains on each rank");
  run_own_chains(scene, rules, o);
  return read_chain_stores(scene, o);
}

OrbitStore read_chain_stores(const Scene& scene, const SamplingOptions& o) {
  const auto frames = static_cast<Eigen::Index>(check_chain_stores(scene, o));
  OrbitStore all = empty_orbit_store(scene);
  // Sized once: growing by IRF would copy the frames again for every IRF.
  all.positions.resize(frames, 3 * static_cast<Eigen::Index>(all.vertices()));
  all.velocities.resize(frames, all.positions.cols());
  all.support.resize(frames, core::kSupportFloats);
  all.frame_palette.reserve(static_cast<size_t>(frames));
  for_each_chain_irf(o, [&all](const IrfFrames& irf) {
    const auto first = static_cast<Eigen::Index>(all.frame_palette.size());
    const Eigen::Index n = irf.frames();
    all.irf_start.push_back(static_cast<std::int32_t>(first));
    all.irf_length.push_back(static_cast<std::int32_t>(n));
    all.irf_palette.push_back(irf.entry);
    all.irf_continues.push_back(irf.continues && first > 0 ? 1 : 0);
    all.positions.middleRows(first, n) = irf.positions;
    all.velocities.middleRows(first, n) = irf.velocities;
    all.support.middleRows(first, n) = irf.support;
    all.frame_palette.insert(all.frame_palette.end(), static_cast<size_t>(n), irf.entry);
  });
  validate_orbit_store(all, o.work_dir.string());
  return all;
}

MergedStore write_chain_stores(const Scene& scene, const SamplingOptions& o,
                               const std::filesystem::path& path) {
  return write_chain_stores(scene, std::vector<SamplingOptions>{o}, path);
}

MergedStore write_chain_stores(const Scene& scene, const std::vector<SamplingOptions>& runs,
                               const std::filesystem::path& path) {
  for (const auto& o : runs) check_chain_stores(scene, o);
  const std::filesystem::path tmp = fmt::format("{}.merging-{}", path.string(), ::getpid());
  MergedStore merged;
  try {
    OrbitStoreAppender out = OrbitStoreAppender::create(tmp, empty_orbit_store(scene), kMergedChunkBytes);
    for (const auto& o : runs) for_each_chain_irf(o, [&out](const IrfFrames& irf) { out.append(irf); });
    merged = {out.irfs(), static_cast<long long>(out.frames())};
    out.close();
    std::filesystem::rename(tmp, path);
  } catch (const std::filesystem::filesystem_error& e) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw OrbitStoreError(fmt::format("{}: cannot write: {}", path.string(), e.code().message()));
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw;
  }
  return merged;
}

}  // namespace phasecast::precompute
