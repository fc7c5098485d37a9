// Streamed chain stores (issue 15): each chain appends its IRFs to an
// extensible orbit store and holds only the IRF it records. The frames equal
// an in-memory recording bit for bit, the bytes written grow linearly with
// the chain, a chain's heap does not grow with it, and resume copes with a
// crash between append and checkpoint, a torn append and a damaged file.

#include "error_of.h"
#include "phasecast/core/hdf5_file.h"
#include "phasecast/precompute/sampling/irf_sampler.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "run_tool.h"
#include "scene_files.h"

#include <gtest/gtest.h>

#include <malloc.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

namespace phasecast::precompute {
namespace {

using testing::error_of;
using testing::scratch_dir;
using testing::tiny_scene_path;
namespace h5 = core::h5;

SamplingOptions one_chain(const std::filesystem::path& dir, int irfs) {
  SamplingOptions o;
  o.chains = 1;
  o.irfs_per_chain = irfs;
  o.seed = 5;
  o.jobs = 1;
  o.work_dir = dir;
  return o;
}

std::filesystem::path chain_file(const SamplingOptions& o, int chain) {
  return o.work_dir / ("chain-00" + std::to_string(chain) + ".h5");
}

// The truth, independent of the sampler's recorder and stores: the chain's
// draws replayed and its frames copied off the simulator into memory, as the
// sampler did before it streamed.
OrbitStore chain_in_memory(const Scene& scene, const PaletteRules& rules, const SamplingOptions& o,
                           int chain) {
  auto sim = make_simulator(scene);
  const SimState rest = settled_rest_state(scene, *sim);
  OrbitStore s = empty_orbit_store(scene);
  std::vector<int> history;
  double at = 0;
  for (int i = 0; i < o.irfs_per_chain; ++i) {
    const IrfDraw d = draw_irf(rules, o.seed, chain, i, history, at);
    if (d.from_rest) {
      sim->reset(rest);
      history.clear();
      at = 0;
    }
    history.push_back(d.entry);
    const auto& entry = scene.palette[static_cast<size_t>(d.entry)];
    s.irf_start.push_back(s.frames());
    s.irf_length.push_back(d.frames);
    s.irf_palette.push_back(d.entry);
    s.irf_continues.push_back(!d.from_rest && i > 0 ? 1 : 0);
    sim->impulse(entry.alpha_impulse);
    for (int f = 0; f < d.frames; ++f) {
      const Eigen::Index row = s.frames();
      s.positions.conservativeResize(row + 1, 3 * sim->vertices());
      s.velocities.conservativeResize(row + 1, 3 * sim->vertices());
      s.support.conservativeResize(row + 1, Eigen::NoChange);
      s.positions.row(row) = sim->state().x.cast<float>().transpose();
      s.velocities.row(row) = sim->state().v.cast<float>().transpose();
      const Eigen::Matrix<double, 3, 4, Eigen::RowMajor> T = sim->support_transform();
      s.support.row(row) = Eigen::Map<const Eigen::Matrix<double, 1, 12>>(T.data()).cast<float>();
      s.frame_palette.push_back(d.entry);
      sim->step(entry.alpha_forcing);
    }
    at = rules.advance(d.entry, at, d.frames);
  }
  return s;
}

void expect_same_frames(const OrbitStore& a, const OrbitStore& b) {
  EXPECT_EQ(a.irf_start, b.irf_start);
  EXPECT_EQ(a.irf_length, b.irf_length);
  EXPECT_EQ(a.irf_palette, b.irf_palette);
  EXPECT_EQ(a.irf_continues, b.irf_continues);
  EXPECT_EQ(a.frame_palette, b.frame_palette);
  ASSERT_EQ(a.positions.rows(), b.positions.rows());
  EXPECT_TRUE(a.positions == b.positions);
  EXPECT_TRUE(a.velocities == b.velocities);
  EXPECT_TRUE(a.support == b.support);
}

class ChainStore : public ::testing::Test {
 protected:
  Scene scene = load_scene_file(tiny_scene_path());
  PaletteRules rules = make_palette_rules(scene);
};

TEST_F(ChainStore, StreamedChainsEqualTheInMemoryRecordingBitForBit) {
  SamplingOptions o = one_chain(scratch_dir("chain_store_truth"), 5);
  o.chains = 2;
  o.jobs = 2;
  sample_own_chains(scene, rules, o);
  OrbitStore all = empty_orbit_store(scene);
  for (int k = 0; k < o.chains; ++k) {
    const OrbitStore truth = chain_in_memory(scene, rules, o, k);
    const OrbitStore streamed = read_orbit_store(chain_file(o, k));  // the unchanged whole-store reader
    expect_same_frames(streamed, truth);
    EXPECT_EQ(streamed.rest_positions, truth.rest_positions);
    EXPECT_EQ(streamed.triangles, truth.triangles);
    EXPECT_EQ(streamed.pinned, truth.pinned);
    EXPECT_EQ(streamed.palette_names, truth.palette_names);
    EXPECT_EQ(streamed.alpha_impulse, truth.alpha_impulse);
    EXPECT_EQ(streamed.scene, truth.scene);
    EXPECT_EQ(streamed.dt, truth.dt);
    for (size_t i = 0; i < truth.irf_start.size(); ++i) {
      IrfFrames irf;
      irf.entry = truth.irf_palette[i];
      irf.continues = truth.irf_continues[i] != 0;
      irf.positions = truth.positions.middleRows(truth.irf_start[i], truth.irf_length[i]);
      irf.velocities = truth.velocities.middleRows(truth.irf_start[i], truth.irf_length[i]);
      irf.support = truth.support.middleRows(truth.irf_start[i], truth.irf_length[i]);
      append_irf(all, irf);
    }
  }
  // Both merges: in memory (sample_irfs' path) and streamed into a file (run's).
  expect_same_frames(read_chain_stores(scene, o), all);
  const auto merged_path = o.work_dir / "orbits.h5";
  const MergedStore merged = write_chain_stores(scene, o, merged_path);
  EXPECT_EQ(merged.irfs, 10);
  EXPECT_EQ(merged.frames, all.frames());
  expect_same_frames(read_orbit_store(merged_path), all);
}

TEST_F(ChainStore, AppenderRejectsABadIrfNamingTheFile) {
  const auto path = scratch_dir("chain_store_bad") / "s.h5";
  auto store = OrbitStoreAppender::create(path, empty_orbit_store(scene));
  IrfFrames irf;
  irf.entry = 1;
  irf.positions = MatrixXfR::Zero(2, 3 * scene.model.vertices());
  irf.velocities = irf.positions;
  irf.support = MatrixXfR::Zero(2, 12);
  irf.positions(1, 0) = std::nanf("");
  EXPECT_EQ(error_of([&] { store.append(irf); }),
            path.string() + ": /frames/positions: IRF 0: NaN or Inf in the frames");
  irf.positions(1, 0) = 0;
  irf.entry = 7;
  EXPECT_EQ(error_of([&] { store.append(irf); }),
            path.string() + ": /irfs/palette: IRF 0: entry out of range");
  irf.entry = 1;
  store.append(irf);
  store.close();
  EXPECT_EQ(read_orbit_store(path).frames(), 2);
  EXPECT_EQ(error_of([&] { OrbitStoreAppender::reopen(path, 2); }),
            path.string() + ": /irfs/start: holds 1 IRFs, expected at least 2");
}

// Bytes handed to write() by this process (Linux), or -1.
long long bytes_written() {
  std::ifstream io("/proc/self/io");
  for (std::string key; io >> key;) {
    long long value = 0;
    io >> value;
    if (key == "wchar:") return value;
  }
  return -1;
}

// Rewriting the whole store after every IRF (as the sampler did) writes
// about K/2 times the final store for K IRFs; appending writes each frame
// once, plus a bounded cost per IRF (the checkpoint, a partial chunk,
// HDF5 metadata).
TEST_F(ChainStore, BytesWrittenGrowLinearlyWithTheChain) {
  if (bytes_written() < 0) GTEST_SKIP() << "no /proc/self/io";
  const SamplingOptions o = one_chain(scratch_dir("chain_store_bytes"), 24);
  // The same file throughout (appended to, never replaced): one inode.
  std::vector<ino_t> inodes;
  SamplingOptions watched = o;
  watched.progress = [&](const SamplingProgress& p) {
    struct stat st {};
    if (p.irfs_done > 0 && ::stat(chain_file(o, 0).c_str(), &st) == 0) inodes.push_back(st.st_ino);
  };
  const long long before = bytes_written();
  sample_own_chains(scene, rules, watched);
  const long long written = bytes_written() - before;
  const auto store = static_cast<long long>(std::filesystem::file_size(chain_file(o, 0)));
  const auto state = static_cast<long long>(std::filesystem::file_size(o.work_dir / "chain-000.state.h5"));
  const OrbitStore s = read_orbit_store(chain_file(o, 0));
  const long long content =
      static_cast<long long>(s.positions.size() + s.velocities.size() + s.support.size() +
                             static_cast<Eigen::Index>(s.frame_palette.size())) *
      4;
  RecordProperty("bytes_written", std::to_string(written));
  RecordProperty("store_bytes", std::to_string(store));
  std::cout << "written " << written << " B, store " << store << " B (frames " << content << " B), state "
            << state << " B x " << o.irfs_per_chain << "\n";
  EXPECT_LE(store, content + content / 4 + (256 << 10)) << "the store holds little besides its frames";
  EXPECT_LE(written, 2 * (store + o.irfs_per_chain * state)) << "each frame is written about once";
  ASSERT_EQ(inodes.size(), 24u);
  EXPECT_EQ(std::count(inodes.begin(), inodes.end(), inodes.front()), 24);
}

// Heap in use (glibc >= 2.33), or -1: what a chain holds, sampled after each of its IRFs.
long long heap_bytes() {
#if defined(__GLIBC__) && (__GLIBC__ > 2 || __GLIBC_MINOR__ >= 33)
  const struct mallinfo2 m = mallinfo2();
  return static_cast<long long>(m.uordblks + m.hblkhd);
#else
  return -1;
#endif
}

TEST_F(ChainStore, ChainMemoryDoesNotGrowWithItsLength) {
  if (heap_bytes() < 0) GTEST_SKIP() << "no mallinfo2";
  SamplingOptions o = one_chain(scratch_dir("chain_store_memory"), 24);
  std::vector<long long> heap, nodes;
  o.progress = [&](const SamplingProgress& p) {
    heap.push_back(heap_bytes());
    nodes.push_back(p.nodes);
  };
  sample_own_chains(scene, rules, o);
  ASSERT_EQ(heap.size(), 25u);  // once when the chain starts, then after each IRF
  // Frames recorded after IRF 6, and what holding them would cost.
  const long long frame_bytes = (2 * 3 * scene.model.vertices() + 13) * 4;
  const long long accumulated = (nodes.back() - nodes[6]) * frame_bytes;
  long long growth = 0;
  for (size_t i = 6; i < heap.size(); ++i) growth = std::max(growth, heap[i] - heap[6]);
  std::cout << "heap after IRF 6: " << heap[6] << " B, largest growth since: " << growth
            << " B; accumulating the frames would add " << accumulated << " B\n";
  EXPECT_LT(growth, accumulated / 4);
}

// Resume tests: a chain of 4 IRFs stopped after 2, then its files altered
// as a crash would leave them, then resumed; the result must be the
// uninterrupted run's, bit for bit.
class ChainStoreResume : public ChainStore {
 protected:
  SamplingOptions stopped(const std::string& name) {
    SamplingOptions o = one_chain(scratch_dir(name), 4);
    o.stop_after_irfs = 2;
    EXPECT_THROW(sample_own_chains(scene, rules, o), SamplingError);
    o.stop_after_irfs = 0;
    o.resume = true;
    return o;
  }
  void expect_resumes_to_the_straight_run(SamplingOptions o, int notices = 0) {
    int seen = 0;
    o.notice = [&](const std::string& line) {
      ++seen;
      EXPECT_NE(line.find("chain 0: "), std::string::npos) << line;
      EXPECT_NE(line.find("sampling the chain again from its start"), std::string::npos) << line;
    };
    sample_own_chains(scene, rules, o);
    EXPECT_EQ(seen, notices);
    expect_same_frames(read_orbit_store(chain_file(o, 0)), chain_in_memory(scene, rules, o, 0));
  }
};

TEST_F(ChainStoreResume, AfterACrashBetweenAppendAndCheckpoint) {
  const SamplingOptions o = stopped("chain_store_extra");
  {
    // IRF 2 appended, its checkpoint never written: resume must drop it.
    auto store = OrbitStoreAppender::reopen(chain_file(o, 0), 2);
    IrfFrames extra;
    extra.entry = 1;
    extra.continues = true;
    extra.positions = MatrixXfR::Constant(3, 3 * scene.model.vertices(), 9.f);
    extra.velocities = extra.positions;
    extra.support = MatrixXfR::Zero(3, 12);
    store.append(extra);
  }
  ASSERT_EQ(read_orbit_store(chain_file(o, 0)).irf_start.size(), 3u);
  expect_resumes_to_the_straight_run(o);
}

TEST_F(ChainStoreResume, AfterATornAppend) {
  const SamplingOptions o = stopped("chain_store_torn");
  {
    // The next IRF's frames half written (positions and velocities, not the
    // rest) and its /irfs row started: start written, the other columns not.
    h5::File f = h5::File::open_write(chain_file(o, 0));
    const MatrixXfR junk = MatrixXfR::Constant(5, 3 * scene.model.vertices(), 7.f);
    f.append_rows("/frames/positions", junk.data(), 5);
    f.append_rows("/frames/velocities", junk.data(), 3);
    const std::int32_t start = 12345;
    f.append_rows("/irfs/start", &start, 1);
    f.flush();
  }
  EXPECT_THROW(read_orbit_store(chain_file(o, 0)), OrbitStoreError);  // torn as it is
  expect_resumes_to_the_straight_run(o);
}

TEST_F(ChainStoreResume, ResamplesAChainWhoseStoreIsDamaged) {
  const SamplingOptions o = stopped("chain_store_damaged");
  std::filesystem::resize_file(chain_file(o, 0), std::filesystem::file_size(chain_file(o, 0)) / 2);
  expect_resumes_to_the_straight_run(o, 1);
}

TEST_F(ChainStoreResume, ResamplesAChainWhoseFramesFailTheirChecksum) {
  const SamplingOptions o = stopped("chain_store_flipped");
  // Flip a byte in the middle of the file, in the raw frames (most of it).
  std::fstream f(chain_file(o, 0), std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(static_cast<std::streamoff>(std::filesystem::file_size(chain_file(o, 0)) * 3 / 4));
  const char byte = static_cast<char>(f.get());
  f.seekp(static_cast<std::streamoff>(std::filesystem::file_size(chain_file(o, 0)) * 3 / 4));
  f.put(static_cast<char>(byte ^ 0x5a));
  f.close();
  expect_resumes_to_the_straight_run(o, 1);
}

TEST_F(ChainStoreResume, ANewRunReplacesTheStoreAndResumesFromItsOwnCheckpoint) {
  SamplingOptions o = stopped("chain_store_fresh");
  o.resume = false;
  o.irfs_per_chain = 1;
  sample_own_chains(scene, rules, o);  // a new run overwrites: its state says 1 IRF, its store holds 1
  o.resume = true;
  o.irfs_per_chain = 4;
  expect_resumes_to_the_straight_run(o);
}

}  // namespace
}  // namespace phasecast::precompute
