#pragma once
// The orbit store: simulated (or imported) orbits, frame by frame, as the
// sampling/reduction stage reads them. HDF5, layout in docs/simulator.md.
// Positions are in the support frame; the support transform of every frame
// takes them to the world.

#include "phasecast/core/eigen_types.h"
#include "phasecast/core/package.h"
#include "phasecast/precompute/sampling/orbit_filter.h"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::precompute {

inline constexpr int kOrbitStoreVersion = 2;  // 2: /irfs/continues

class OrbitStoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct OrbitStore {
  std::string scene;
  std::string source;                // "phasecast-simulator" or "import"
  std::string scene_file;            // absolute path of the scene file that made it (empty: not known)
  double dt = 0;                     // s between frames
  MatrixXfR rest_positions;          // V x 3
  MatrixXuR triangles;               // F x 3 surface triangles
  MatrixXuR segments;                // E x 2 rod edges (0 rows: no rods)
  std::vector<std::uint8_t> pinned;  // V
  // Palette (names, alpha_I, alpha_F: D x k, kinematics as core::SupportKinematics).
  std::vector<std::string> palette_names;
  MatrixXfR alpha_impulse;
  MatrixXfR alpha_forcing;
  std::vector<core::SupportKinematics> kinematics;
  // Frames.
  MatrixXfR positions;                      // N x 3V
  MatrixXfR velocities;                     // N x 3V
  std::vector<std::int32_t> frame_palette;  // N: entry active at the frame
  MatrixXfR support;                        // N x 12: row-major 3x4 support-to-world transform
  // IRFs: consecutive frame ranges.
  std::vector<std::int32_t> irf_start;
  std::vector<std::int32_t> irf_length;
  std::vector<std::int32_t> irf_palette;
  // 1: the IRF continues the previous one's motion (its first frame follows the
  // previous IRF's last frame by one step); 0: it starts from the settled rest.
  // Eq. 8's velocity at an IRF start is the pre-impulse one, so it needs this.
  std::vector<std::uint8_t> irf_continues;

  int frames() const { return static_cast<int>(positions.rows()); }
  int vertices() const { return static_cast<int>(rest_positions.rows()); }
};

// Checks shapes, index ranges, finiteness and that the IRFs tile the frames
// in order. Throws OrbitStoreError naming `source` and the dataset.
void validate_orbit_store(const OrbitStore& store, const std::string& source);

// Validates, then writes atomically (temporary file renamed over `path`).
void write_orbit_store(const OrbitStore& store, const std::filesystem::path& path);

// Reads and validates; one-line OrbitStoreError for anything else.
OrbitStore read_orbit_store(const std::filesystem::path& path);

// One IRF's frames: all a sampling chain holds in memory while it records,
// the unit a streamed store appends.
struct IrfFrames {
  int entry = 0;
  bool continues = false;  // continues the previous IRF's motion (ignored for a store's first IRF)
  MatrixXfR positions;     // n x 3V
  MatrixXfR velocities;    // n x 3V
  MatrixXfR support;       // n x 12

  int frames() const { return static_cast<int>(positions.rows()); }
};

// Appends `irf` to an in-memory store (one resize of its frame matrices).
void append_irf(OrbitStore& store, const IrfFrames& irf);

// Frame chunk size of a store appended to after every IRF (a chain store):
// small, as every append rewrites its first chunk (checksummed whole). On the
// tiny cloth (77 frames of 1.2 KB per IRF) 64 KiB chunks wrote 5.6 times the
// store, 8 KiB ones 1.4 times.
inline constexpr std::uint64_t kAppendChunkBytes = std::uint64_t{8} << 10;

// An orbit store on disk that grows one IRF at a time (the sampler's chain
// stores, docs/sampling.md). Same layout as write_orbit_store's, so
// read_orbit_store reads it, but /frames and /irfs are extensible: an append
// writes only the new IRF, never the rows before it. Its frames are written
// and flushed first, its /irfs row last, so the /irfs table is the truth:
// frame rows past the IRFs it lists are an append that did not finish.
class OrbitStoreAppender {
 public:
  // Creates `path` atomically (replacing any file) with the scene, mesh and
  // palette of `header` (its frames are ignored) and no IRFs. Frames are
  // chunked by about `frame_chunk_bytes` (at least one frame per chunk): an
  // append rewrites the chunk it starts in, and readers read whole chunks.
  static OrbitStoreAppender create(const std::filesystem::path& path, const OrbitStore& header,
                                   std::uint64_t frame_chunk_bytes = kAppendChunkBytes);
  // Opens a store for appending after its first `irfs` IRFs, dropping every
  // row after them (an append that a crash tore or left unacknowledged), and
  // checks the frames it keeps. A store written whole by write_orbit_store
  // is first rewritten extensible. OrbitStoreError (one line) if it holds
  // fewer IRFs or cannot be read.
  static OrbitStoreAppender reopen(const std::filesystem::path& path, int irfs);

  OrbitStoreAppender(OrbitStoreAppender&&) noexcept;
  OrbitStoreAppender& operator=(OrbitStoreAppender&&) noexcept;
  ~OrbitStoreAppender();

  // Checks the IRF (shapes, palette entry, finite frames) and appends it.
  void append(const IrfFrames& irf);
  // The /irfs rows appended so far, read back from the file.
  IrfList irf_table() const;
  int irfs() const { return irfs_; }
  std::int64_t frames() const { return frames_; }
  const std::filesystem::path& path() const { return path_; }
  // Flushes and closes the file (also done by the destructor); appends then fail.
  void close();

 private:
  struct Hdf5;
  OrbitStoreAppender(std::filesystem::path path, std::unique_ptr<Hdf5> h5);
  [[noreturn]] void fail(const std::string& where, const std::string& what) const;

  std::filesystem::path path_;
  std::unique_ptr<Hdf5> h5_;
  int irfs_ = 0;
  std::int64_t frames_ = 0;
  Eigen::Index columns_ = 0;  // 3V
  int palette_size_ = 0;
};

// Reads a store one IRF at a time, so that chains merge in constant memory.
class OrbitStoreReader {
 public:
  // Checks the format, the header and that the /irfs table tiles the frames.
  explicit OrbitStoreReader(const std::filesystem::path& path);
  OrbitStoreReader(OrbitStoreReader&&) noexcept;
  ~OrbitStoreReader();

  // Scene, mesh and palette, without frames.
  const OrbitStore& header() const { return header_; }
  const IrfList& irfs() const { return irfs_; }
  // IRF `irf`'s frames into `out` (its buffers reused); checks them finite
  // and their palette entry the IRF's.
  void read(int irf, IrfFrames& out) const;

 private:
  struct Hdf5;
  std::filesystem::path path_;
  std::unique_ptr<Hdf5> h5_;
  OrbitStore header_;
  IrfList irfs_;
};

}  // namespace phasecast::precompute
