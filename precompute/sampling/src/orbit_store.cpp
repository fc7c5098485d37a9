// HDF5 layout of the orbit store (docs/simulator.md). Reuses the RAII HDF5
// layer of phasecast_core so dtype checks and error handling match the package.

#include "phasecast/precompute/sampling/orbit_store.h"

#include "phasecast/core/kinematics_rows.h"

#include "phasecast/core/hdf5_file.h"

#include <fmt/format.h>

namespace phasecast::precompute {
namespace {

namespace h5 = core::h5;
constexpr const char* kFormat = "phasecast-orbits";

}  // namespace

void validate_orbit_store(const OrbitStore& s, const std::string& source) {
  const auto fail = [&](const std::string& where, const std::string& what) {
    throw OrbitStoreError(fmt::format("{}: {}: {}", source, where, what));
  };
  const Eigen::Index V = s.rest_positions.rows(), N = s.positions.rows();
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
  if (N == 0) fail("/frames/positions", "expected at least one frame");
  if (s.positions.cols() != 3 * V || s.velocities.rows() != N || s.velocities.cols() != 3 * V) {
    fail("/frames/velocities", fmt::format("expected positions and velocities of {} x {}", N, 3 * V));
  }
  if (!s.positions.allFinite() || !s.velocities.allFinite())
    fail("/frames/positions", "NaN or Inf in the frames");
  if (static_cast<Eigen::Index>(s.frame_palette.size()) != N)
    fail("/frames/palette", fmt::format("expected {} entries", N));
  if (s.support.rows() != N || s.support.cols() != core::kSupportFloats || !s.support.allFinite()) {
    fail("/frames/support", fmt::format("expected {} x 12 finite transforms", N));
  }
  const size_t n_irf = s.irf_start.size();
  if (n_irf == 0 || s.irf_length.size() != n_irf || s.irf_palette.size() != n_irf ||
      s.irf_continues.size() != n_irf) {
    fail("/irfs/start",
         "expected one or more IRFs with start, length, palette and continues of equal counts");
  }
  if (s.irf_continues[0] != 0) fail("/irfs/continues", "the first IRF cannot continue an earlier one");
  std::int32_t next = 0;
  for (size_t i = 0; i < n_irf; ++i) {
    if (s.irf_start[i] != next || s.irf_length[i] < 1) {
      fail("/irfs/start",
           fmt::format("IRF {} must start at frame {} with length >= 1 (IRFs tile the frames in order)", i,
                       next));
    }
    if (s.irf_palette[i] < 0 || s.irf_palette[i] >= D)
      fail("/irfs/palette", fmt::format("IRF {}: entry out of range", i));
    for (std::int32_t f = s.irf_start[i]; f < s.irf_start[i] + s.irf_length[i] && f < N; ++f) {
      if (s.frame_palette[static_cast<size_t>(f)] != s.irf_palette[i]) {
        fail("/frames/palette", fmt::format("frame {} differs from its IRF's palette entry", f));
      }
    }
    next += s.irf_length[i];
  }
  if (next != N) fail("/irfs/length", fmt::format("IRFs cover {} frames, expected {}", next, N));
}

void write_orbit_store(const OrbitStore& s, const std::filesystem::path& path) {
  validate_orbit_store(s, path.string());
  try {
    h5::write_atomically(path, [&s](h5::File& f) {
      f.write_attribute("format", std::string(kFormat));
      f.write_attribute("format_version", std::int32_t{kOrbitStoreVersion});
      f.write_attribute("scene", s.scene);
      f.write_attribute("source", s.source);
      f.write_attribute("dt", s.dt);
      f.write("/mesh/rest_positions", s.rest_positions);
      f.write("/mesh/triangles", s.triangles);
      if (s.segments.rows() > 0) f.write("/mesh/segments", s.segments);  // only scenes with rods
      f.write("/mesh/pinned", s.pinned);
      f.write_strings("/palette/names", s.palette_names);
      f.write("/palette/alpha_impulse", s.alpha_impulse);
      f.write("/palette/alpha_forcing", s.alpha_forcing);
      f.write("/palette/kinematics", core::kinematics_to_rows(s.kinematics));
      f.write("/frames/positions", s.positions);
      f.write("/frames/velocities", s.velocities);
      f.write("/frames/palette", s.frame_palette);
      f.write("/frames/support", s.support);
      f.write("/irfs/start", s.irf_start);
      f.write("/irfs/length", s.irf_length);
      f.write("/irfs/palette", s.irf_palette);
      f.write("/irfs/continues", s.irf_continues);
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
    if (!f.has_attribute("format") || f.read_attribute_string("format") != kFormat) {
      r.fail("/ attribute format", fmt::format("expected \"{}\" (is this an orbit store?)", kFormat));
    }
    const int version = static_cast<int>(f.read_attribute_number("format_version"));
    if (version != kOrbitStoreVersion) {
      r.fail("/ attribute format_version", fmt::format("expected {}, got {}", kOrbitStoreVersion, version));
    }
    OrbitStore s;
    s.scene = f.read_attribute_string("scene");
    s.source = f.read_attribute_string("source");
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
    s.positions = r.matrix<float>("/frames/positions");
    s.velocities = r.matrix<float>("/frames/velocities");
    s.frame_palette = r.vector<std::int32_t>("/frames/palette");
    s.support = r.matrix<float>("/frames/support");
    s.irf_start = r.vector<std::int32_t>("/irfs/start");
    s.irf_length = r.vector<std::int32_t>("/irfs/length");
    s.irf_palette = r.vector<std::int32_t>("/irfs/palette");
    s.irf_continues = r.vector<std::uint8_t>("/irfs/continues");
    validate_orbit_store(s, path.string());
    return s;
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", path.string(), e.what()));
  }
}

}  // namespace phasecast::precompute
