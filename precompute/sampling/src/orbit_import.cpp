#include "phasecast/precompute/sampling/orbit_import.h"

#include "phasecast/precompute/simulation/obj_mesh.h"
#include "phasecast/precompute/simulation/scene.h"
#include "phasecast/precompute/simulation/scene_fields.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
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

}  // namespace

OrbitStore import_orbits(const std::filesystem::path& manifest,
                         const std::function<void(int, int)>& progress) {
  toml::table root;
  try {
    root = toml::parse_file(manifest.string());
  } catch (const toml::parse_error& e) {
    throw SceneError(fmt::format("{}:{}:{}: {}", manifest.string(), e.source().begin.line,
                                 e.source().begin.column, e.description()));
  }
  const auto dir = manifest.parent_path();
  Fields top(root, manifest.string(), "");
  OrbitStore s;
  s.source = "import";
  s.scene = top.string("scene");
  s.dt = top.positive("dt");

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

  // Collect every IRF's frame files first so progress knows the total.
  auto irfs = top.tables("irf");
  if (irfs.empty()) top.fail("irf", "at least one [[irf]]");
  std::vector<std::pair<int, std::vector<std::filesystem::path>>> plan;
  int total = 0;
  for (auto& irf : irfs) {
    const std::string name = irf.string("palette");
    const auto it = std::find(s.palette_names.begin(), s.palette_names.end(), name);
    if (it == s.palette_names.end()) irf.fail("palette", "the name of a [[palette]] entry");
    plan.emplace_back(static_cast<int>(it - s.palette_names.begin()), obj_frames(irf, dir));
    total += static_cast<int>(plan.back().second.size());
    irf.finish();
  }
  const bool has_rest = top.has("rest");
  const auto rest_path = has_rest ? dir / top.string("rest") : plan.front().second.front();
  const ObjMesh rest = read_obj(rest_path);
  std::vector<int> pinned_list;
  if (top.has("pinned")) {
    const auto* list = root["pinned"].as_array();
    if (!list) top.fail("pinned", "an array of vertex indices");
    for (double p : top.numbers("pinned", list->size())) {
      if (p < 0 || p >= static_cast<double>(rest.vertices.rows()) || p != std::floor(p)) {
        top.fail("pinned", fmt::format("vertex indices in [0, {})", rest.vertices.rows()));
      }
      pinned_list.push_back(static_cast<int>(p));
    }
  }
  top.finish();

  const auto V = rest.vertices.rows();
  s.rest_positions = positions_row(rest).reshaped<Eigen::RowMajor>(V, 3);
  s.triangles = rest.triangles.cast<std::uint32_t>();
  s.pinned.assign(static_cast<size_t>(V), 0);
  for (int p : pinned_list) s.pinned[static_cast<size_t>(p)] = 1;
  s.positions.resize(total, 3 * V);
  s.velocities.resize(total, 3 * V);
  s.support = MatrixXfR::Zero(total, core::kSupportFloats);
  int n = 0;
  for (const auto& [entry, files] : plan) {
    s.irf_start.push_back(n);
    s.irf_length.push_back(static_cast<std::int32_t>(files.size()));
    s.irf_palette.push_back(entry);
    for (const auto& file : files) {
      const ObjMesh m = read_obj(file);
      if (m.vertices.rows() != V || m.triangles != rest.triangles) {
        throw SceneError(
            fmt::format("{}: expected the topology of {} ({} vertices, {} triangles), got {} vertices, {} "
                        "triangles",
                        file.string(), rest_path.string(), V, rest.triangles.rows(), m.vertices.rows(),
                        m.triangles.rows()));
      }
      s.positions.row(n) = positions_row(m);
      s.frame_palette.push_back(entry);
      s.support(n, 0) = s.support(n, 5) = s.support(n, 10) = 1;  // identity 3x4
      ++n;
      if (progress) progress(n, total);
    }
    const int first = s.irf_start.back(), len = s.irf_length.back();
    for (int f = first; f < first + len; ++f) {
      if (f > first) {
        s.velocities.row(f) = (s.positions.row(f) - s.positions.row(f - 1)) / static_cast<float>(s.dt);
      } else if (len > 1) {
        s.velocities.row(f) = (s.positions.row(f + 1) - s.positions.row(f)) / static_cast<float>(s.dt);
      } else {
        s.velocities.row(f).setZero();
      }
    }
  }
  validate_orbit_store(s, manifest.string());
  return s;
}

}  // namespace phasecast::precompute
