// HDF5 layout of the orbit store (docs/simulator.md). Reuses the RAII HDF5
// layer of phasecast_core so dtype checks and error handling match the package.

#include "phasecast/precompute/sampling/orbit_store.h"

#include "phasecast/core/kinematics_rows.h"

#include "phasecast/core/hdf5_file.h"

#include <fmt/format.h>

#include <unistd.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <tuple>

namespace phasecast::precompute {
namespace {

namespace h5 = core::h5;
constexpr const char* kFormat = "phasecast-orbits";

constexpr const char* kPositions = "/frames/positions";
constexpr const char* kVelocities = "/frames/velocities";
constexpr const char* kFramePalette = "/frames/palette";
constexpr const char* kSupport = "/frames/support";
constexpr const char* kIrfStart = "/irfs/start";
constexpr const char* kIrfLength = "/irfs/length";
constexpr const char* kIrfPalette = "/irfs/palette";
constexpr const char* kIrfContinues = "/irfs/continues";

// The /irfs table grows by one row per append, which rewrites its chunk.
constexpr std::uint64_t kIrfChunkBytes = 1 << 10;

using Fail = std::function<void(const std::string& where, const std::string& what)>;

// Everything but the frames and IRFs: attributes, mesh, palette.
void validate_header(const OrbitStore& s, const Fail& fail) {
  const Eigen::Index V = s.rest_positions.rows();
  const auto D = static_cast<Eigen::Index>(s.palette_names.size());
  if (!(s.dt > 0)) fail("/ attribute dt", fmt::format("expected a positive frame spacing, got {}", s.dt));
  if (V == 0 || s.rest_positions.cols() != 3) fail("/mesh/rest_positions", "expected V x 3 with V >= 1");
  if ((s.triangles.array() >= static_cast<std::uint32_t>(V)).any())
    fail("/mesh/triangles", "vertex index out of range");
  if (s.triangles.cols() != 3 && s.triangles.rows() > 0) fail("/mesh/triangles", "expected F x 3");
  if (s.segments.rows() > 0 &&
      (s.segments.cols() != 2 || (s.segments.array() >= static_cast<std::uint32_t>(V)).any())) {
    fail("/mesh/segments", "expected E x 2 vertex indices in range");
  }
  if (static_cast<Eigen::Index>(s.pinned.size()) != V)
    fail("/mesh/pinned", fmt::format("expected {} entries", V));
  if (D == 0) fail("/palette/names", "expected at least one palette entry");
  if (s.alpha_impulse.rows() != D || s.alpha_forcing.rows() != D ||
      s.alpha_forcing.cols() != s.alpha_impulse.cols()) {
    fail("/palette/alpha_impulse", fmt::format("expected {} rows matching /palette/alpha_forcing", D));
  }
  if (static_cast<Eigen::Index>(s.kinematics.size()) != D)
    fail("/palette/kinematics", fmt::format("expected {} rows", D));
}

// Checks that the IRFs tile the frames in order from frame 0 and name
// entries of the palette; returns the frames they cover.
std::int64_t tile_irfs(const IrfList& t, std::int64_t palette_size, const Fail& fail) {
  const size_t n = t.size();
  if (t.length.size() != n || t.palette.size() != n || t.continues.size() != n)
    fail(kIrfStart, "expected one or more IRFs with start, length, palette and continues of equal counts");
  if (n > 0 && t.continues[0] != 0) fail(kIrfContinues, "the first IRF cannot continue an earlier one");
  std::int64_t next = 0;
  for (size_t i = 0; i < n; ++i) {
    if (t.start[i] != next || t.length[i] < 1) {
      fail(kIrfStart,
           fmt::format("IRF {} must start at frame {} with length >= 1 (IRFs tile the frames in order)", i,
                       next));
    }
    if (t.palette[i] < 0 || t.palette[i] >= palette_size)
      fail(kIrfPalette, fmt::format("IRF {}: entry out of range", i));
    next += t.length[i];
  }
  return next;
}

Fail reader_fail(const h5::Reader& r) {
  return [&r](const std::string& where, const std::string& what) { r.fail(where, what); };
}

void write_header(h5::File& f, const OrbitStore& s) {
  f.write_attribute("format", std::string(kFormat));
  f.write_attribute("format_version", std::int32_t{kOrbitStoreVersion});
  f.write_attribute("scene", s.scene);
  f.write_attribute("source", s.source);
  if (!s.scene_file.empty()) f.write_attribute("scene_file", s.scene_file);
  f.write_attribute("dt", s.dt);
  f.write("/mesh/rest_positions", s.rest_positions);
  f.write("/mesh/triangles", s.triangles);
  if (s.segments.rows() > 0) f.write("/mesh/segments", s.segments);  // only scenes with rods
  f.write("/mesh/pinned", s.pinned);
  f.write_strings("/palette/names", s.palette_names);
  f.write("/palette/alpha_impulse", s.alpha_impulse);
  f.write("/palette/alpha_forcing", s.alpha_forcing);
  f.write("/palette/kinematics", core::kinematics_to_rows(s.kinematics));
}

void check_format(const h5::File& f, const h5::Reader& r) {
  if (!f.has_attribute("format") || f.read_attribute_string("format") != kFormat) {
    r.fail("/ attribute format", fmt::format("expected \"{}\" (is this an orbit store?)", kFormat));
  }
  const int version = static_cast<int>(f.read_attribute_number("format_version"));
  if (version != kOrbitStoreVersion) {
    r.fail("/ attribute format_version", fmt::format("expected {}, got {}", kOrbitStoreVersion, version));
  }
}

OrbitStore read_header(const h5::File& f, const h5::Reader& r) {
  OrbitStore s;
  s.scene = f.read_attribute_string("scene");
  s.source = f.read_attribute_string("source");
  if (f.has_attribute("scene_file")) s.scene_file = f.read_attribute_string("scene_file");
  s.dt = f.read_attribute_number("dt");
  s.rest_positions = r.matrix<float>("/mesh/rest_positions");
  s.triangles = r.matrix<std::uint32_t>("/mesh/triangles");
  s.segments = f.exists("/mesh/segments") ? r.matrix<std::uint32_t>("/mesh/segments") : MatrixXuR(0, 2);
  s.pinned = r.vector<std::uint8_t>("/mesh/pinned");
  s.palette_names = r.strings("/palette/names");
  s.alpha_impulse = r.matrix<float>("/palette/alpha_impulse");
  s.alpha_forcing = r.matrix<float>("/palette/alpha_forcing");
  const MatrixXfR k = r.matrix<float>("/palette/kinematics");
  if (k.cols() != core::kKinematicsColumns) r.fail("/palette/kinematics", "expected D x 11");
  s.kinematics = core::kinematics_from_rows(k);
  s.support.resize(0, core::kSupportFloats);
  return s;
}

// Rows [first, first + count) of a dataset already checked by the caller.
template <class T>
void read_rows(const h5::File& f, const h5::Reader& r, const char* name, std::int64_t first,
               std::int64_t count, T* out) {
  try {
    f.read_rows(name, static_cast<std::uint64_t>(first), static_cast<std::uint64_t>(count), out);
  } catch (const h5::Failure& e) {
    r.fail(name, e.what());
  }
}

// IRF `i` of table `t`, frames and all, into `out`: finite, and every
// frame's palette entry its IRF's.
void read_irf(const h5::File& f, const h5::Reader& r, const IrfList& t, size_t i, Eigen::Index columns,
              IrfFrames& out) {
  const std::int64_t first = t.start[i], n = t.length[i];
  out.entry = t.palette[i];
  out.continues = t.continues[i] != 0;
  out.positions.resize(n, columns);
  out.velocities.resize(n, columns);
  out.support.resize(n, core::kSupportFloats);
  std::vector<std::int32_t> palette(static_cast<size_t>(n));
  read_rows(f, r, kPositions, first, n, out.positions.data());
  read_rows(f, r, kVelocities, first, n, out.velocities.data());
  read_rows(f, r, kSupport, first, n, out.support.data());
  read_rows(f, r, kFramePalette, first, n, palette.data());
  if (!out.positions.allFinite() || !out.velocities.allFinite())
    r.fail(kPositions, fmt::format("NaN or Inf in the frames of IRF {}", i));
  if (!out.support.allFinite()) r.fail(kSupport, fmt::format("NaN or Inf in the transforms of IRF {}", i));
  for (std::int64_t k = 0; k < n; ++k) {
    if (palette[static_cast<size_t>(k)] != out.entry)
      r.fail(kFramePalette, fmt::format("frame {} differs from its IRF's palette entry", first + k));
  }
}

// The length of a 1-D or 2-D dataset's first dimension, checking its dtype
// and row shape but not yet its storage: the rows of a torn append may be
// declared and not stored, and are dropped before anything is read.
std::int64_t declared_rows(const h5::File& f, const h5::Reader& r, const char* name, h5::Dtype dtype,
                           std::uint64_t columns) {
  if (!f.exists(name)) r.fail(name, "missing dataset");
  h5::DatasetInfo info;
  try {
    info = f.info(name);
  } catch (const h5::Failure& e) {
    r.fail(name, e.what());
  }
  const bool rows_match = columns ? info.dims.size() == 2 && info.dims[1] == columns : info.dims.size() == 1;
  if (info.dtype != dtype || !rows_match) {
    r.fail(name,
           fmt::format("expected rows of {} {} values, got a {} {} dataset", columns ? columns : 1,
                       h5::dtype_name(dtype), h5::describe_dims(info.dims), h5::dtype_name(info.dtype)));
  }
  if (!info.extensible) r.fail(name, "expected an extensible dataset (written by OrbitStoreAppender)");
  return static_cast<std::int64_t>(info.dims[0]);
}

// The first `count` rows of the /irfs table.
IrfList read_irf_rows(const h5::File& f, const h5::Reader& r, int count) {
  IrfList t;
  t.start.resize(static_cast<size_t>(count));
  t.length.resize(t.start.size());
  t.palette.resize(t.start.size());
  t.continues.resize(t.start.size());
  const auto rows = [&](const char* name, h5::Dtype dtype, auto* out) {
    const std::int64_t held = declared_rows(f, r, name, dtype, 0);
    if (held < count) r.fail(name, fmt::format("holds {} IRFs, expected at least {}", held, count));
    read_rows(f, r, name, 0, count, out);
  };
  rows(kIrfStart, h5::Dtype::i32, t.start.data());
  rows(kIrfLength, h5::Dtype::i32, t.length.data());
  rows(kIrfPalette, h5::Dtype::i32, t.palette.data());
  rows(kIrfContinues, h5::Dtype::u8, t.continues.data());
  return t;
}

// Drops every row after the first `irfs` IRFs and their `frames` frames:
// an append that a crash tore or left unacknowledged.
void keep_rows(h5::File& f, const h5::Reader& r, int irfs, std::int64_t frames, std::uint64_t columns) {
  for (const auto& [name, dtype, width] :
       {std::tuple{kPositions, h5::Dtype::f32, columns}, std::tuple{kVelocities, h5::Dtype::f32, columns},
        std::tuple{kFramePalette, h5::Dtype::i32, std::uint64_t{0}},
        std::tuple{kSupport, h5::Dtype::f32, std::uint64_t{core::kSupportFloats}}}) {
    const std::int64_t held = declared_rows(f, r, name, dtype, width);
    if (held < frames)
      r.fail(name, fmt::format("holds {} frames, expected at least the {} of its first {} IRFs", held, frames,
                               irfs));
    f.set_rows(name, static_cast<std::uint64_t>(frames));
  }
  for (const char* name : {kIrfStart, kIrfLength, kIrfPalette, kIrfContinues})
    f.set_rows(name, static_cast<std::uint64_t>(irfs));
  f.flush();
}

// Every kept frame must be stored and intact (Fletcher-32), so a damaged
// store is found on resume rather than when the chains are merged: reads
// them back, one IRF at a time.
void check_kept_frames(const h5::File& f, const h5::Reader& r, const IrfList& t, Eigen::Index columns) {
  std::uint64_t N = 0;
  for (const std::int32_t n : t.length) N += static_cast<std::uint64_t>(n);
  const auto width = static_cast<std::uint64_t>(columns);
  r.require_shape(kPositions, h5::Dtype::f32, {N, width});
  r.require_shape(kVelocities, h5::Dtype::f32, {N, width});
  r.require_shape(kFramePalette, h5::Dtype::i32, {N});
  r.require_shape(kSupport, h5::Dtype::f32, {N, core::kSupportFloats});
  IrfFrames irf;
  for (size_t i = 0; i < t.size(); ++i) read_irf(f, r, t, i, columns, irf);
}

bool extensible_store(const std::filesystem::path& path) {
  try {
    const h5::File f = h5::File::open_read(path);
    return f.exists(kPositions) && f.info(kPositions).extensible;
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", path.string(), e.what()));
  }
}

// A store written whole by write_orbit_store (a work folder of an earlier
// version) becomes an extensible one holding its first `irfs` IRFs.
void rewrite_extensible(const std::filesystem::path& path, int irfs) {
  const std::filesystem::path tmp = fmt::format("{}.extensible-{}", path.string(), ::getpid());
  std::error_code error;
  try {
    const OrbitStoreReader whole(path);
    auto out = OrbitStoreAppender::create(tmp, whole.header());
    IrfFrames irf;
    for (size_t i = 0; i < std::min(whole.irfs().size(), static_cast<size_t>(irfs)); ++i) {
      whole.read(static_cast<int>(i), irf);
      out.append(irf);
    }
    out.close();
  } catch (const OrbitStoreError&) {
    std::filesystem::remove(tmp, error);
    throw;
  }
  std::filesystem::rename(tmp, path, error);
  if (error) throw OrbitStoreError(fmt::format("{}: cannot replace it: {}", path.string(), error.message()));
}

}  // namespace

void validate_orbit_store(const OrbitStore& s, const std::string& source) {
  const Fail fail = [&](const std::string& where, const std::string& what) {
    throw OrbitStoreError(fmt::format("{}: {}: {}", source, where, what));
  };
  validate_header(s, fail);
  const Eigen::Index V = s.rest_positions.rows(), N = s.positions.rows();
  if (N == 0) fail(kPositions, "expected at least one frame");
  if (s.positions.cols() != 3 * V || s.velocities.rows() != N || s.velocities.cols() != 3 * V) {
    fail(kVelocities, fmt::format("expected positions and velocities of {} x {}", N, 3 * V));
  }
  if (!s.positions.allFinite() || !s.velocities.allFinite()) fail(kPositions, "NaN or Inf in the frames");
  if (static_cast<Eigen::Index>(s.frame_palette.size()) != N)
    fail(kFramePalette, fmt::format("expected {} entries", N));
  if (s.support.rows() != N || s.support.cols() != core::kSupportFloats || !s.support.allFinite()) {
    fail(kSupport, fmt::format("expected {} x 12 finite transforms", N));
  }
  if (s.irf_start.empty())
    fail(kIrfStart, "expected one or more IRFs with start, length, palette and continues of equal counts");
  const IrfList t{s.irf_start, s.irf_length, s.irf_palette, s.irf_continues};
  const std::int64_t covered = tile_irfs(t, static_cast<std::int64_t>(s.palette_names.size()), fail);
  for (size_t i = 0; i < t.size(); ++i) {
    for (std::int32_t f = t.start[i]; f < t.start[i] + t.length[i] && f < N; ++f) {
      if (s.frame_palette[static_cast<size_t>(f)] != t.palette[i]) {
        fail(kFramePalette, fmt::format("frame {} differs from its IRF's palette entry", f));
      }
    }
  }
  if (covered != N) fail(kIrfLength, fmt::format("IRFs cover {} frames, expected {}", covered, N));
}

void write_orbit_store(const OrbitStore& s, const std::filesystem::path& path) {
  validate_orbit_store(s, path.string());
  try {
    h5::write_atomically(path, [&s](h5::File& f) {
      write_header(f, s);
      f.write(kPositions, s.positions);
      f.write(kVelocities, s.velocities);
      f.write(kFramePalette, s.frame_palette);
      f.write(kSupport, s.support);
      f.write(kIrfStart, s.irf_start);
      f.write(kIrfLength, s.irf_length);
      f.write(kIrfPalette, s.irf_palette);
      f.write(kIrfContinues, s.irf_continues);
    });
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: cannot write: {}", path.string(), e.what()));
  }
}

OrbitStore read_orbit_store(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throw OrbitStoreError(fmt::format("{}: no such file", path.string()));
  try {
    const h5::File f = h5::File::open_read(path);
    const h5::Reader r = h5::checked_reader<OrbitStoreError>(f, path.string());
    check_format(f, r);
    OrbitStore s = read_header(f, r);
    s.positions = r.matrix<float>(kPositions);
    s.velocities = r.matrix<float>(kVelocities);
    s.frame_palette = r.vector<std::int32_t>(kFramePalette);
    s.support = r.matrix<float>(kSupport);
    s.irf_start = r.vector<std::int32_t>(kIrfStart);
    s.irf_length = r.vector<std::int32_t>(kIrfLength);
    s.irf_palette = r.vector<std::int32_t>(kIrfPalette);
    s.irf_continues = r.vector<std::uint8_t>(kIrfContinues);
    validate_orbit_store(s, path.string());
    return s;
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", path.string(), e.what()));
  }
}

void append_irf(OrbitStore& s, const IrfFrames& irf) {
  const Eigen::Index first = s.frames(), n = irf.frames();
  s.irf_start.push_back(static_cast<std::int32_t>(first));
  s.irf_length.push_back(static_cast<std::int32_t>(n));
  s.irf_palette.push_back(irf.entry);
  s.irf_continues.push_back(irf.continues && first > 0 ? 1 : 0);
  s.positions.conservativeResize(first + n, irf.positions.cols());
  s.positions.bottomRows(n) = irf.positions;
  s.velocities.conservativeResize(first + n, irf.velocities.cols());
  s.velocities.bottomRows(n) = irf.velocities;
  s.support.conservativeResize(first + n, core::kSupportFloats);
  s.support.bottomRows(n) = irf.support;
  s.frame_palette.insert(s.frame_palette.end(), static_cast<size_t>(n), irf.entry);
}

// ---- OrbitStoreAppender -------------------------------------------------------

struct OrbitStoreAppender::Hdf5 {
  h5::File file;
};

OrbitStoreAppender::OrbitStoreAppender(std::filesystem::path path, std::unique_ptr<Hdf5> h5)
    : path_(std::move(path)), h5_(std::move(h5)) {}
OrbitStoreAppender::OrbitStoreAppender(OrbitStoreAppender&&) noexcept = default;
OrbitStoreAppender& OrbitStoreAppender::operator=(OrbitStoreAppender&&) noexcept = default;
OrbitStoreAppender::~OrbitStoreAppender() = default;

void OrbitStoreAppender::fail(const std::string& where, const std::string& what) const {
  throw OrbitStoreError(fmt::format("{}: {}: {}", path_.string(), where, what));
}

OrbitStoreAppender OrbitStoreAppender::create(const std::filesystem::path& path, const OrbitStore& header,
                                              std::uint64_t frame_chunk_bytes) {
  validate_header(header, [&](const std::string& where, const std::string& what) {
    throw OrbitStoreError(fmt::format("{}: {}: {}", path.string(), where, what));
  });
  const auto columns = static_cast<std::uint64_t>(3 * header.vertices());
  try {
    h5::write_atomically(path, [&](h5::File& f) {
      write_header(f, header);
      f.create_rows<float>(kPositions, {columns}, frame_chunk_bytes);
      f.create_rows<float>(kVelocities, {columns}, frame_chunk_bytes);
      f.create_rows<std::int32_t>(kFramePalette, {}, frame_chunk_bytes);
      f.create_rows<float>(kSupport, {core::kSupportFloats}, frame_chunk_bytes);
      f.create_rows<std::int32_t>(kIrfStart, {}, kIrfChunkBytes);
      f.create_rows<std::int32_t>(kIrfLength, {}, kIrfChunkBytes);
      f.create_rows<std::int32_t>(kIrfPalette, {}, kIrfChunkBytes);
      f.create_rows<std::uint8_t>(kIrfContinues, {}, kIrfChunkBytes);
    });
    OrbitStoreAppender a(path, std::make_unique<Hdf5>(Hdf5{h5::File::open_write(path)}));
    a.columns_ = static_cast<Eigen::Index>(columns);
    a.palette_size_ = static_cast<int>(header.palette_names.size());
    return a;
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: cannot create: {}", path.string(), e.what()));
  }
}

OrbitStoreAppender OrbitStoreAppender::reopen(const std::filesystem::path& path, int irfs) {
  if (!std::filesystem::exists(path)) throw OrbitStoreError(fmt::format("{}: no such file", path.string()));
  if (irfs < 0) throw OrbitStoreError(fmt::format("{}: cannot keep {} IRFs", path.string(), irfs));
  if (!extensible_store(path)) rewrite_extensible(path, irfs);
  try {
    OrbitStoreAppender a(path, std::make_unique<Hdf5>(Hdf5{h5::File::open_write(path)}));
    h5::File& f = a.h5_->file;
    const h5::Reader r = h5::checked_reader<OrbitStoreError>(f, path.string());
    check_format(f, r);
    a.columns_ = 3 * static_cast<Eigen::Index>(r.require("/mesh/rest_positions", h5::Dtype::f32, 2).dims[0]);
    a.palette_size_ = static_cast<int>(r.require("/palette/names", h5::Dtype::string, 1).dims[0]);
    const IrfList t = read_irf_rows(f, r, irfs);
    a.frames_ = tile_irfs(t, a.palette_size_, reader_fail(r));
    a.irfs_ = irfs;
    keep_rows(f, r, irfs, a.frames_, static_cast<std::uint64_t>(a.columns_));
    check_kept_frames(f, r, t, a.columns_);
    return a;
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", path.string(), e.what()));
  }
}

void OrbitStoreAppender::append(const IrfFrames& irf) {
  const int k = irfs_;
  const Eigen::Index n = irf.frames();
  if (!h5_) fail("/", fmt::format("closed before IRF {} (expected an open store)", k));
  if (n < 1) fail(kPositions, fmt::format("IRF {}: expected at least one frame", k));
  if (irf.positions.cols() != columns_ || irf.velocities.rows() != n || irf.velocities.cols() != columns_)
    fail(kVelocities, fmt::format("IRF {}: expected positions and velocities of {} x {}", k, n, columns_));
  if (!irf.positions.allFinite() || !irf.velocities.allFinite())
    fail(kPositions, fmt::format("IRF {}: NaN or Inf in the frames", k));
  if (irf.support.rows() != n || irf.support.cols() != core::kSupportFloats || !irf.support.allFinite())
    fail(kSupport, fmt::format("IRF {}: expected {} x 12 finite transforms", k, n));
  if (irf.entry < 0 || irf.entry >= palette_size_)
    fail(kIrfPalette, fmt::format("IRF {}: entry out of range", k));
  if (frames_ + n > std::numeric_limits<std::int32_t>::max())
    fail(kIrfStart, fmt::format("IRF {}: frame {} past the int32 range of /irfs/start", k, frames_ + n));
  const auto first = static_cast<std::uint64_t>(frames_), rows = static_cast<std::uint64_t>(n),
             row = static_cast<std::uint64_t>(k);
  const std::vector<std::int32_t> palette(static_cast<size_t>(n), irf.entry);
  const auto start = static_cast<std::int32_t>(frames_), length = static_cast<std::int32_t>(n);
  const std::uint8_t continues = irf.continues && k > 0 ? 1 : 0;
  try {
    h5::File& f = h5_->file;
    // Frames first and flushed, the /irfs row last: a crash in between
    // leaves frames that no IRF lists, which reopen() drops.
    f.write_rows(kPositions, first, irf.positions.data(), rows);
    f.write_rows(kVelocities, first, irf.velocities.data(), rows);
    f.write_rows(kFramePalette, first, palette.data(), rows);
    f.write_rows(kSupport, first, irf.support.data(), rows);
    f.flush();
    f.write_rows(kIrfStart, row, &start, 1);
    f.write_rows(kIrfLength, row, &length, 1);
    f.write_rows(kIrfPalette, row, &irf.entry, 1);
    f.write_rows(kIrfContinues, row, &continues, 1);
    f.flush();
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: cannot append IRF {}: {}", path_.string(), k, e.what()));
  }
  ++irfs_;
  frames_ += n;
}

IrfList OrbitStoreAppender::irf_table() const {
  if (!h5_) fail("/irfs", "closed (expected an open store)");
  try {
    const h5::Reader r = h5::checked_reader<OrbitStoreError>(h5_->file, path_.string());
    return read_irf_rows(h5_->file, r, irfs_);
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", path_.string(), e.what()));
  }
}

void OrbitStoreAppender::close() {
  if (!h5_) return;
  try {
    h5_->file.flush();
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: cannot close: {}", path_.string(), e.what()));
  }
  h5_.reset();
}

// ---- OrbitStoreReader ---------------------------------------------------------

struct OrbitStoreReader::Hdf5 {
  h5::File file;
};

OrbitStoreReader::OrbitStoreReader(OrbitStoreReader&&) noexcept = default;
OrbitStoreReader::~OrbitStoreReader() = default;

OrbitStoreReader::OrbitStoreReader(const std::filesystem::path& path) : path_(path) {
  if (!std::filesystem::exists(path)) throw OrbitStoreError(fmt::format("{}: no such file", path.string()));
  try {
    h5_ = std::make_unique<Hdf5>(Hdf5{h5::File::open_read(path)});
    const h5::File& f = h5_->file;
    const h5::Reader r = h5::checked_reader<OrbitStoreError>(f, path.string());
    check_format(f, r);
    header_ = read_header(f, r);
    validate_header(header_, reader_fail(r));
    irfs_.start = r.vector<std::int32_t>(kIrfStart);
    irfs_.length = r.vector<std::int32_t>(kIrfLength);
    irfs_.palette = r.vector<std::int32_t>(kIrfPalette);
    irfs_.continues = r.vector<std::uint8_t>(kIrfContinues);
    const std::int64_t frames =
        tile_irfs(irfs_, static_cast<std::int64_t>(header_.palette_names.size()), reader_fail(r));
    const auto N = static_cast<std::uint64_t>(frames),
               columns = static_cast<std::uint64_t>(3 * header_.vertices());
    r.require_shape(kPositions, h5::Dtype::f32, {N, columns});
    r.require_shape(kVelocities, h5::Dtype::f32, {N, columns});
    r.require_shape(kSupport, h5::Dtype::f32, {N, core::kSupportFloats});
    r.require_shape(kFramePalette, h5::Dtype::i32, {N});
    // require_shape() treats 0 as "any": an empty store must hold no frames.
    if (N == 0 && f.rows(kPositions) != 0) r.fail(kPositions, "frames past the IRFs (expected none)");
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", path.string(), e.what()));
  }
}

void OrbitStoreReader::read(int irf, IrfFrames& out) const {
  try {
    const h5::Reader r = h5::checked_reader<OrbitStoreError>(h5_->file, path_.string());
    if (irf < 0 || static_cast<size_t>(irf) >= irfs_.size())
      r.fail(kIrfStart, fmt::format("no IRF {} (it holds {})", irf, irfs_.size()));
    read_irf(h5_->file, r, irfs_, static_cast<size_t>(irf), 3 * header_.vertices(), out);
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", path_.string(), e.what()));
  }
}

}  // namespace phasecast::precompute
