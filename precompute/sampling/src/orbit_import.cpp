#include "phasecast/precompute/sampling/orbit_import.h"

#include "phasecast/core/phase_space.h"

#include "phasecast/precompute/simulation/obj_mesh.h"
#include "phasecast/precompute/simulation/scene.h"
#include "phasecast/precompute/simulation/scene_fields.h"

#include <Eigen/LU>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

namespace phasecast::precompute {
namespace {

using detail::Fields;

core::SupportKinematics read_kinematics(Fields k) {
  core::SupportKinematics s;
  const auto f3 = [](const Eigen::Vector3d& v) {
    return std::array<float, 3>{static_cast<float>(v.x()), static_cast<float>(v.y()),
                                static_cast<float>(v.z())};
  };
  const std::string motion = k.string("motion");
  if (motion != "rotational" && motion != "translational")
    k.fail("motion", "\"rotational\" or \"translational\"");
  s.rotational = motion == "rotational";
  s.axis = f3(k.vec3("axis"));
  s.pivot = f3(k.vec3("pivot", Eigen::Vector3d::Zero()));
  s.rate = static_cast<float>(k.number("rate", 0));
  if (k.has("range")) {
    const auto r = k.numbers("range", 2);
    if (!(r[0] <= r[1])) k.fail("range", "[min, max] with min <= max");
    s.range_min = static_cast<float>(r[0]);
    s.range_max = static_cast<float>(r[1]);
  }
  s.pulse_tau = static_cast<float>(k.number("pulse_tau", 0));
  k.finish();
  return s;
}

std::vector<std::filesystem::path> obj_frames(Fields& irf, const std::filesystem::path& dir) {
  const auto folder = dir / irf.string("frames");
  if (!std::filesystem::is_directory(folder))
    irf.fail("frames", "a folder of OBJ frames (relative to the manifest)");
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(folder)) {
    if (e.path().extension() == ".obj") files.push_back(e.path());
  }
  if (files.empty()) irf.fail("frames", "a folder with at least one .obj file");
  std::sort(files.begin(), files.end());  // frame order is file-name order
  return files;
}

MatrixXfR positions_row(const ObjMesh& m) {
  MatrixXfR row(1, 3 * m.vertices.rows());
  for (Eigen::Index i = 0; i < m.vertices.rows(); ++i)
    for (int k = 0; k < 3; ++k) row(0, 3 * i + k) = static_cast<float>(m.vertices(i, k));
  return row;
}

using Transform = Eigen::Matrix<double, 3, 4, Eigen::RowMajor>;

// One [[irf]] of the manifest: its palette entry, whether it continues the
// previous IRF's motion (eq. 8 needs it), its frames in order and, when the
// other tool moved the support, the support-to-world transform of each.
struct ImportedIrf {
  int entry = 0;
  std::uint8_t continues = 0;
  std::vector<std::filesystem::path> files;
  std::vector<Transform> support;  // empty: the identity throughout
};

// `support = "FILE"`: one line per frame, the 12 numbers of [R | t] row by
// row; R must be a rotation (a rigid support).
std::vector<Transform> read_support_file(Fields& irf, const std::filesystem::path& dir, size_t frames) {
  const auto path = dir / irf.string("support");
  std::ifstream in(path);
  if (!in) irf.fail("support", "a text file of support transforms (relative to the manifest)");
  std::vector<Transform> out;
  int line_number = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_number;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[line.find_first_not_of(" \t")] == '#')
      continue;
    std::istringstream words(line);
    Transform T;
    for (int k = 0; k < 12; ++k) {
      if (!(words >> T(k / 4, k % 4)))
        throw SceneError(fmt::format("{}:{}: expected 12 numbers (the 3x4 [R | t], row by row)",
                                     path.string(), line_number));
    }
    const Eigen::Matrix3d R = T.leftCols<3>();
    if (!T.allFinite() || (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-4 ||
        R.determinant() < 0) {
      throw SceneError(fmt::format("{}:{}: expected a rotation in the first 3 columns (a rigid support)",
                                   path.string(), line_number));
    }
    out.push_back(T);
  }
  if (out.size() != frames) {
    throw SceneError(fmt::format("{}: {} transforms for the {} OBJ frames of {}", path.string(), out.size(),
                                 frames, (dir / irf.string("frames")).string()));
  }
  return out;
}

toml::table parse_manifest(const std::filesystem::path& manifest) {
  try {
    return toml::parse_file(manifest.string());
  } catch (const toml::parse_error& e) {
    throw SceneError(fmt::format("{}:{}:{}: {}", manifest.string(), e.source().begin.line,
                                 e.source().begin.column, e.description()));
  }
}

void read_palette(Fields& top, OrbitStore& s) {
  auto entries = top.tables("palette");
  if (entries.empty()) top.fail("palette", "at least one [[palette]] entry");
  std::vector<Eigen::Vector3d> alpha_i, alpha_f;
  for (auto& e : entries) {
    const std::string name = e.string("name");
    if (std::count(s.palette_names.begin(), s.palette_names.end(), name))
      e.fail("name", "a name not used by an earlier entry");
    s.palette_names.push_back(name);
    alpha_i.push_back(e.vec3("alpha_impulse"));
    alpha_f.push_back(e.vec3("alpha_forcing"));
    s.kinematics.push_back(e.has("kinematics") ? read_kinematics(e.table("kinematics"))
                                               : core::SupportKinematics{});
    e.finish();
  }
  s.alpha_impulse.resize(static_cast<Eigen::Index>(alpha_i.size()), 3);
  s.alpha_forcing.resize(static_cast<Eigen::Index>(alpha_i.size()), 3);
  for (size_t d = 0; d < alpha_i.size(); ++d) {
    s.alpha_impulse.row(static_cast<Eigen::Index>(d)) = alpha_i[d].cast<float>().transpose();
    s.alpha_forcing.row(static_cast<Eigen::Index>(d)) = alpha_f[d].cast<float>().transpose();
  }
}

// Every IRF's frame files, collected first so progress knows the total.
std::vector<ImportedIrf> plan_irfs(Fields& top, const OrbitStore& s, const std::filesystem::path& dir) {
  auto irfs = top.tables("irf");
  if (irfs.empty()) top.fail("irf", "at least one [[irf]]");
  std::vector<ImportedIrf> plan;
  for (auto& irf : irfs) {
    const std::string name = irf.string("palette");
    const auto it = std::find(s.palette_names.begin(), s.palette_names.end(), name);
    if (it == s.palette_names.end()) irf.fail("palette", "the name of a [[palette]] entry");
    ImportedIrf p;
    p.entry = static_cast<int>(it - s.palette_names.begin());
    p.continues = irf.flag("continues", false) ? 1 : 0;
    if (p.continues && plan.empty())
      irf.fail("continues", "false for the first [[irf]] (nothing precedes it)");
    p.files = obj_frames(irf, dir);
    if (irf.has("support")) p.support = read_support_file(irf, dir, p.files.size());
    plan.push_back(std::move(p));
    irf.finish();
  }
  return plan;
}

std::vector<int> read_pinned(Fields& top, const toml::table& root, Eigen::Index vertices) {
  std::vector<int> pinned;
  if (!top.has("pinned")) return pinned;
  const auto* list = root["pinned"].as_array();
  if (!list) top.fail("pinned", "an array of vertex indices");
  for (double p : top.numbers("pinned", list->size())) {
    if (p < 0 || p >= static_cast<double>(vertices) || p != std::floor(p))
      top.fail("pinned", fmt::format("vertex indices in [0, {})", vertices));
    pinned.push_back(static_cast<int>(p));
  }
  return pinned;
}

// Reads every frame of the plan into the store; each must have the rest mesh's topology.
// x = R^T (x_world - t), row by row.
Eigen::MatrixX3d to_support_frame(const Eigen::MatrixX3d& world, const Transform& T) {
  return (world.rowwise() - T.col(3).transpose()) * T.leftCols<3>();
}

// World positions (`positions = "world"`) are taken into the support's frame.
void read_frames(const std::vector<ImportedIrf>& plan, const ObjMesh& rest,
                 const std::filesystem::path& rest_path, bool world, OrbitStore& s,
                 const std::function<void(int, int)>& progress) {
  int total = 0;
  for (const auto& p : plan) total += static_cast<int>(p.files.size());
  const auto V = rest.vertices.rows();
  s.positions.resize(total, 3 * V);
  s.support = MatrixXfR::Zero(total, core::kSupportFloats);
  int n = 0;
  for (const auto& p : plan) {
    s.irf_start.push_back(n);
    s.irf_length.push_back(static_cast<std::int32_t>(p.files.size()));
    s.irf_palette.push_back(p.entry);
    s.irf_continues.push_back(p.continues);
    for (size_t f = 0; f < p.files.size(); ++f) {
      const auto& file = p.files[f];
      ObjMesh m = read_obj(file);
      if (m.vertices.rows() != V || m.triangles != rest.triangles) {
        throw SceneError(
            fmt::format("{}: expected the topology of {} ({} vertices, {} triangles), got {} vertices, {} "
                        "triangles",
                        file.string(), rest_path.string(), V, rest.triangles.rows(), m.vertices.rows(),
                        m.triangles.rows()));
      }
      const Transform T = p.support.empty() ? Transform::Identity() : p.support[f];
      if (world) m.vertices = to_support_frame(m.vertices, T);
      s.positions.row(n) = positions_row(m);
      s.frame_palette.push_back(p.entry);
      s.support.row(n) = Eigen::Map<const Eigen::Matrix<double, 1, 12>>(T.data()).cast<float>();
      ++n;
      if (progress) progress(n, total);
    }
  }
}

}  // namespace

OrbitStore import_orbits(const std::filesystem::path& manifest,
                         const std::function<void(int, int)>& progress) {
  const toml::table root = parse_manifest(manifest);
  const auto dir = manifest.parent_path();
  Fields top(root, manifest.string(), "");
  OrbitStore s;
  s.source = "import";
  s.scene = top.string("scene");
  s.dt = top.positive("dt");
  read_palette(top, s);
  const std::vector<ImportedIrf> plan = plan_irfs(top, s, dir);
  const auto rest_path = top.has("rest") ? dir / top.string("rest") : plan.front().files.front();
  ObjMesh rest = read_obj(rest_path);
  const std::vector<int> pinned = read_pinned(top, root, rest.vertices.rows());
  const std::string positions = top.optional_string("positions").value_or("support");
  if (positions != "support" && positions != "world") top.fail("positions", "\"support\" or \"world\"");
  top.finish();
  // A rest taken from the first frame is in that frame's coordinates; a named one is in the support's.
  if (positions == "world" && !top.has("rest") && !plan.front().support.empty())
    rest.vertices = to_support_frame(rest.vertices, plan.front().support.front());

  const auto V = rest.vertices.rows();
  s.rest_positions = positions_row(rest).reshaped<Eigen::RowMajor>(V, 3);
  s.triangles = rest.triangles.cast<std::uint32_t>();
  s.pinned.assign(static_cast<size_t>(V), 0);
  for (int p : pinned) s.pinned[static_cast<size_t>(p)] = 1;
  read_frames(plan, rest, rest_path, positions == "world", s, progress);
  s.velocities = core::orbit_velocities(s.positions, s.irf_start, s.irf_length, s.irf_continues, s.dt);
  validate_orbit_store(s, manifest.string());
  return s;
}

}  // namespace phasecast::precompute
