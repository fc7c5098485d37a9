#include "phasecast/precompute/package/package_builder.h"

#include "phasecast/core/kinematics_rows.h"

#include "phasecast/core/mesh_geometry.h"
#include "phasecast/core/phase_space.h"

#include "phasecast/precompute/sampling/scene_palette.h"

#include "phasecast/precompute/reduction/phase_portrait.h"
#include "phasecast/precompute/sampling/orbit_store.h"
#include "phasecast/precompute/simulation/render_surface.h"

#include "phasecast/core/hdf5_file.h"

#include <fmt/format.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

namespace h5 = core::h5;

// Cells along one edge of a prop face of length `extent`.
int face_cells(double extent, double cell) {
  return cell > 0 ? std::clamp(static_cast<int>(std::ceil(extent / cell - 1e-9)), 1, kMaxPropCells) : 1;
}

// Appends one face of an axis-aligned box as an nu x nv grid of quads with
// its own points (hard edges: each face keeps its outward normal). Plain
// scalar writes: fixed-size Eigen temporaries here trip GCC 12's -Warray-bounds.
void add_box_face(core::SceneMesh& m, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int axis,
                  int side, double cell) {
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  const int nu = face_cells(hi(u) - lo(u), cell), nv = face_cells(hi(v) - lo(v), cell);
  const Eigen::Index base = m.rest_positions.rows(), first_tri = m.triangles.rows();
  m.rest_positions.conservativeResize(base + (nu + 1) * (nv + 1), 3);
  m.normals.conservativeResize(m.rest_positions.rows(), 3);
  m.triangles.conservativeResize(first_tri + 2 * nu * nv, 3);
  Eigen::Index point = base;
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i, ++point) {
      m.rest_positions(point, axis) = static_cast<float>(side ? hi(axis) : lo(axis));
      m.rest_positions(point, u) = static_cast<float>(lo(u) + (hi(u) - lo(u)) * i / nu);
      m.rest_positions(point, v) = static_cast<float>(lo(v) + (hi(v) - lo(v)) * j / nv);
      for (int k = 0; k < 3; ++k) m.normals(point, k) = k == axis ? (side ? 1.0f : -1.0f) : 0.0f;
    }
  }
  Eigen::Index tri = first_tri;
  const auto at = [&](int i, int j) { return static_cast<std::uint32_t>(base + j * (nu + 1) + i); };
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      // (u, v, axis) is right-handed: counter-clockwise seen from +axis; reversed on the -axis face.
      const std::uint32_t quad[2][3] = {{at(i, j), at(i + 1, j), at(i + 1, j + 1)},
                                        {at(i, j), at(i + 1, j + 1), at(i, j + 1)}};
      for (const auto& t : quad) {
        m.triangles(tri, 0) = t[0];
        m.triangles(tri, 1) = side ? t[1] : t[2];
        m.triangles(tri, 2) = side ? t[2] : t[1];
        ++tri;
      }
    }
  }
}

// Points add_box appends for this box.
Eigen::Index box_points(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double cell) {
  Eigen::Index n = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    n += 2 * (face_cells(hi(u) - lo(u), cell) + 1) * (face_cells(hi(v) - lo(v), cell) + 1);
  }
  return n;
}

// Appends one axis-aligned box, each face tessellated into cells of about `cell` metres.
void add_box(core::SceneMesh& m, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double cell) {
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) add_box_face(m, lo, hi, axis, side, cell);
}

// Surface points that get a back-side copy, ascending: those of sheet
// triangles (no corner moved by a vertex of a tetrahedron).
std::vector<int> back_side_points(const RenderSurface& surface) {
  const auto P = static_cast<size_t>(surface.points());
  std::vector<std::uint8_t> sheet(P, 0);
  const auto solid = [&](Eigen::Index t, int k) {
    return surface.solid[static_cast<size_t>(surface.triangles(t, k))];
  };
  for (Eigen::Index t = 0; t < surface.triangles.rows(); ++t) {
    if (solid(t, 0) || solid(t, 1) || solid(t, 2)) continue;
    for (int k = 0; k < 3; ++k) sheet[static_cast<size_t>(surface.triangles(t, k))] = 1;
  }
  std::vector<int> out;
  for (size_t p = 0; p < P; ++p)
    if (sheet[p]) out.push_back(static_cast<int>(p));
  return out;
}

// How obstacle i looks to the appearance stage (the default look when the
// scene lists none).
PropLook prop_look(const Scene& scene, size_t i) {
  return i < scene.props.size() ? scene.props[i] : PropLook{};
}

// Scene points of obstacle i: none for a box that is not drawn.
Eigen::Index prop_points(const Scene& scene, size_t i) {
  const PropLook look = prop_look(scene, i);
  const auto& o = scene.model.obstacles[i];
  return look.drawn ? box_points(o.min, o.max, look.cell) : 0;
}

// Scene points the props add: the boxes in obstacle order, then the meshes.
Eigen::Index prop_points(const Scene& scene) {
  Eigen::Index n = 0;
  for (size_t i = 0; i < scene.model.obstacles.size(); ++i) n += prop_points(scene, i);
  for (const auto& mesh : scene.prop_meshes) n += mesh.positions.rows();
  return n;
}

// Appends a prop mesh as it is: its points, normals and triangles.
void add_prop_mesh(core::SceneMesh& m, const PropMesh& mesh) {
  const Eigen::Index base = m.rest_positions.rows(), first_tri = m.triangles.rows();
  m.rest_positions.conservativeResize(base + mesh.positions.rows(), 3);
  m.rest_positions.bottomRows(mesh.positions.rows()) = mesh.positions.cast<float>();
  m.normals.conservativeResize(m.rest_positions.rows(), 3);
  m.normals.bottomRows(mesh.normals.rows()) = mesh.normals.cast<float>();
  m.triangles.conservativeResize(first_tri + mesh.triangles.rows(), 3);
  m.triangles.bottomRows(mesh.triangles.rows()) =
      (mesh.triangles.array() + static_cast<int>(base)).cast<std::uint32_t>();
}

// x-bar and U_u of the scene points from those of the simulated vertices:
// W x-bar + d and W U_u (a back side shares its front's rows); static points
// keep their rest position and zero rows. sigma and rel_error are those of
// the simulated displacements the SVD saw.
core::Reduction embedded_reduction(const core::SceneMesh& mesh, const Embedding& embedding,
                                   const DisplacementBasis& basis) {
  const VertexEmbedding& W = embedding.weights;
  core::Reduction out;
  const MatrixXfR mean = embed_positions(embedding, basis.mean_shape);
  out.mean_shape = Eigen::Map<const VectorXf>(mesh.rest_positions.data(), 3 * mesh.points());
  for (Eigen::Index p = 0; p < mesh.points(); ++p)
    if (embeds(W, p)) out.mean_shape.segment(3 * p, 3) = mean.col(0).segment(3 * p, 3);
  out.U_u = embed_rows(W, basis.U_u);
  out.singular_values = basis.singular_values;
  out.rel_error = basis.rel_error;
  return out;
}

std::string listed(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return "[" + out + "]";
}

}  // namespace

std::vector<SupportVelocity> kept_support_velocities(const Scene& scene, const IrfList& irfs,
                                                     const std::vector<int>& kept) {
  std::vector<SupportVelocity> held;
  // The forcing is the velocity an entry holds (a jolt's pulse comes on top and returns to rest).
  for (const auto& e : scene.palette)
    held.push_back(SupportVelocity{e.alpha_forcing.x(), e.alpha_forcing.y(), e.alpha_forcing.z()});
  const std::vector<SupportVelocity> all =
      support_velocities(irfs.start, irfs.length, irfs.palette, irfs.continues, held);
  std::vector<SupportVelocity> out;
  for (int i : kept) {
    const auto first = all.begin() + irfs.start[static_cast<size_t>(i)];
    out.insert(out.end(), first, first + irfs.length[static_cast<size_t>(i)]);
  }
  return out;
}

void check_orbit_store_matches(const Scene& scene, const OrbitIndex& o) {
  std::vector<std::string> names;
  for (const auto& e : scene.palette) names.push_back(e.name);
  std::string differs;
  const auto add = [&differs](const std::string& what) { differs += (differs.empty() ? "" : "; ") + what; };
  if (o.vertices != scene.model.vertices())
    add(fmt::format("{} vertices in the store, {} in the scene", o.vertices, scene.model.vertices()));
  if (names != o.palette_names)
    add(fmt::format("palette {} in the store, {} in the scene (names and order must match)",
                    listed(o.palette_names), listed(names)));
  // A range the store names (an import manifest's kinematics) must be the scene's support range.
  for (size_t d = 0; d < o.kinematics.size() && names == o.palette_names; ++d) {
    const auto& k = o.kinematics[d];
    const core::SupportKinematics want = entry_kinematics(scene, static_cast<int>(d));
    if (k.range_max > k.range_min &&
        (std::abs(k.range_min - want.range_min) > 1e-5 || std::abs(k.range_max - want.range_max) > 1e-5))
      add(fmt::format("'{}' has the range [{}, {}] in the store, [{}, {}] in the scene's [support]", names[d],
                      k.range_min, k.range_max, want.range_min, want.range_max));
  }
  if (std::abs(o.dt - scene.simulation.frame_dt) > 1e-12)
    add(fmt::format("dt {} in the store, frame_dt {} in the scene", o.dt, scene.simulation.frame_dt));
  if (differs.empty()) return;
  throw std::invalid_argument(
      fmt::format("orbit store of scene '{}' ({} vertices, {} palette entries, dt {}) does not belong to "
                  "scene '{}': {}",
                  o.scene, o.vertices, o.palette_names.size(), o.dt, scene.name, differs));
}

void apply_view(const ViewSettings& view, core::PackageAttributes& a) {
  const auto f = [](double v) { return static_cast<float>(v); };
  if (view.eye) {
    const auto &e = *view.eye, &t = *view.target, &u = view.up;
    a.camera = std::array<float, 10>{f(e.x()), f(e.y()), f(e.z()), f(t.x()), f(t.y()),
                                     f(t.z()), f(u.x()), f(u.y()), f(u.z()), f(view.fov_y_deg)};
  }
  a.floor = view.floor;
  if (view.floor_height) a.floor_height = f(*view.floor_height);
  a.light = view.light;
  if (view.exposure) a.exposure = f(*view.exposure);
}

OrbitIndex read_orbit_index(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throw OrbitStoreError(fmt::format("{}: no such file", path.string()));
  try {
    const h5::File f = h5::File::open_read(path);
    const h5::Reader r = h5::checked_reader<OrbitStoreError>(f, path.string());
    OrbitIndex o;
    o.scene = r.text("scene");
    o.dt = r.number("dt");
    o.palette_names = r.strings("/palette/names");
    const MatrixXfR k = r.matrix<float>("/palette/kinematics");
    if (k.cols() != core::kKinematicsColumns) r.fail("/palette/kinematics", "expected D x 11");
    o.kinematics = core::kinematics_from_rows(k);
    o.vertices = static_cast<int>(r.require("/mesh/rest_positions", h5::Dtype::f32, 2).dims[0]);
    o.irfs.start = r.vector<std::int32_t>("/irfs/start");
    o.irfs.length = r.vector<std::int32_t>("/irfs/length");
    o.irfs.palette = r.vector<std::int32_t>("/irfs/palette");
    o.irfs.continues = r.vector<std::uint8_t>("/irfs/continues");
    r.require_shape("/frames/support", h5::Dtype::f32, {0, core::kSupportFloats});
    o.support = r.matrix<float>("/frames/support");
    // IRFs must tile the frames in order (as validate_orbit_store checks for a loaded store).
    std::int64_t next = 0;
    for (size_t i = 0; i < o.irfs.size(); ++i) {
      if (i >= o.irfs.length.size() || i >= o.irfs.palette.size() || i >= o.irfs.continues.size() ||
          o.irfs.start[i] != next || (i == 0 && o.irfs.continues[i] != 0) || o.irfs.length[i] < 1 ||
          o.irfs.palette[i] < 0 || o.irfs.palette[i] >= static_cast<std::int32_t>(o.palette_names.size())) {
        throw OrbitStoreError(
            fmt::format("{}: /irfs: IRF {} does not continue the frames in order", path.string(), i));
      }
      next += o.irfs.length[i];
    }
    if (o.irfs.size() == 0 || next != o.support.rows())
      throw OrbitStoreError(
          fmt::format("{}: /irfs: IRFs cover {} frames, expected {}", path.string(), next, o.support.rows()));
    return o;
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", path.string(), e.what()));
  }
}

core::SceneMesh scene_mesh(const Scene& scene) {
  const auto& model = scene.model;
  const RenderSurface surface = render_surface(scene);
  core::SceneMesh m;
  const MatrixXfR rest = embed_positions(surface.embedding(), model.rest.cast<float>());  // W X + d
  m.rest_positions = Eigen::Map<const MatrixXfR>(rest.data(), surface.points(), 3);
  m.triangles = surface.triangles.cast<std::uint32_t>();
  m.normals = core::vertex_normals(m.rest_positions, m.triangles);  // front side
  core::add_back_side(m.rest_positions, m.normals, m.triangles, back_side_points(surface));
  m.deformable.assign(static_cast<size_t>(m.rest_positions.rows()), 1);
  for (size_t i = 0; i < model.obstacles.size(); ++i) {
    const PropLook look = prop_look(scene, i);
    if (look.drawn) add_box(m, model.obstacles[i].min, model.obstacles[i].max, look.cell);
  }
  for (const auto& mesh : scene.prop_meshes) add_prop_mesh(m, mesh);
  m.deformable.resize(static_cast<size_t>(m.rest_positions.rows()), 0);
  m.attached.assign(static_cast<size_t>(m.rest_positions.rows()), 1);  // everything rides on the support
  return m;
}

Embedding scene_point_embedding(const Scene& scene) {
  const RenderSurface surface = render_surface(scene);
  const auto back = back_side_points(surface);
  const Eigen::Index P = surface.points(), B = static_cast<Eigen::Index>(back.size());
  std::vector<Eigen::Triplet<double>> w;
  for (Eigen::Index p = 0; p < P + B; ++p) {
    const Eigen::Index front = p < P ? p : back[static_cast<size_t>(p - P)];
    for (VertexEmbedding::InnerIterator it(surface.weights, front); it; ++it)
      w.emplace_back(static_cast<int>(p), static_cast<int>(it.col()), it.value());
  }
  Embedding e;
  e.weights.resize(P + B + prop_points(scene), scene.model.vertices());  // the props' rows stay empty
  e.weights.setFromTriplets(w.begin(), w.end());
  e.offsets = surface.offsets;  // tubes are closed: no back side shares an offset
  return e;
}

MatrixXfR scene_point_albedo(const Scene& scene) {
  const RenderSurface surface = render_surface(scene);
  const auto back = back_side_points(surface);
  const Eigen::Index P = surface.points(), B = static_cast<Eigen::Index>(back.size());
  MatrixXfR rho(P + B + prop_points(scene), 3);
  Eigen::Index p = 0;
  for (; p < P + B; ++p) {
    const Eigen::Index front = p < P ? p : back[static_cast<size_t>(p - P)];
    rho.row(p) =
        scene.bodies[static_cast<size_t>(surface.body[static_cast<size_t>(front)])].albedo.cast<float>();
  }
  // The props' points follow in obstacle order, each box's points in one block, then the meshes'.
  for (size_t i = 0; i < scene.model.obstacles.size(); ++i) {
    const Eigen::Index n = prop_points(scene, i);
    rho.middleRows(p, n).rowwise() = prop_look(scene, i).albedo.cast<float>().transpose();
    p += n;
  }
  for (const auto& mesh : scene.prop_meshes) {
    rho.middleRows(p, mesh.positions.rows()).rowwise() = mesh.albedo.cast<float>().transpose();
    p += mesh.positions.rows();
  }
  return rho;
}

void check_package_options(const PackageOptions& o) {
  if (!(std::isfinite(o.beta) && o.beta >= 0) || !(std::isfinite(o.blend_lambda) && o.blend_lambda > 0) ||
      !(std::isfinite(o.filter.dead_end_fraction) && o.filter.dead_end_fraction >= 0) ||
      o.filter.min_frames < 1) {
    throw std::invalid_argument(
        fmt::format("package options: expected --beta >= 0, --blend-lambda > 0, --dead-end-fraction >= 0 and "
                    "--min-irf-frames >= 1, got {}, {}, {}, {}",
                    o.beta, o.blend_lambda, o.filter.dead_end_fraction, o.filter.min_frames));
  }
}

PackageBuild build_package(const Scene& scene, const PaletteRules& rules, const OrbitIndex& orbits,
                           const DisplacementBasis& basis, const PackageOptions& o) {
  check_package_options(o);
  check_orbit_store_matches(scene, orbits);
  PackageBuild out;
  core::ScenePackage& pkg = out.package;
  // Eq. 8 and beta over every sampled node, then filtering in that metric.
  const MatrixXfR qdot_all = core::orbit_velocities(basis.q_u, orbits.irfs.start, orbits.irfs.length,
                                                    orbits.irfs.continues, orbits.dt);
  const double beta_all = o.beta > 0 ? o.beta : default_beta(basis.q_u, qdot_all);
  OrbitFilterOptions filter = o.filter;
  for (const auto& e : scene.palette) filter.entry_names.push_back(e.name);
  out.filter = filter_orbits(basis.q_u, qdot_all, beta_all, orbits.irfs, filter);
  // Kept IRFs, renumbered: their nodes become consecutive rows.
  auto& p = pkg.portrait;
  Eigen::Index nodes = 0;
  for (int i : out.filter.kept) nodes += orbits.irfs.length[static_cast<size_t>(i)];
  const int r = basis.rank();
  p.q_u.resize(nodes, r);
  p.qdot_u.resize(nodes, r);
  p.q_a.resize(nodes, 0);
  p.support.resize(nodes, core::kSupportFloats);
  Eigen::Index row = 0;
  for (int i : out.filter.kept) {
    const auto k = static_cast<size_t>(i);
    const std::int32_t first = orbits.irfs.start[k], len = orbits.irfs.length[k];
    p.irf_start.push_back(static_cast<std::int32_t>(row));
    p.irf_length.push_back(len);
    p.irf_palette.push_back(orbits.irfs.palette[k]);
    p.q_u.middleRows(row, len) = basis.q_u.middleRows(first, len);
    p.qdot_u.middleRows(row, len) = qdot_all.middleRows(first, len);
    p.support.middleRows(row, len) = orbits.support.middleRows(first, len);
    row += len;
  }
  const double beta = o.beta > 0 ? o.beta : default_beta(p.q_u, p.qdot_u);
  p.nearest_irf =
      nearest_irf_cache(p.q_u, p.qdot_u, beta, p.irf_start, p.irf_length, p.irf_palette, rules.size(),
                        kept_support_velocities(scene, orbits.irfs, out.filter.kept));
  pkg.mesh = scene_mesh(scene);
  pkg.reduction = embedded_reduction(pkg.mesh, scene_point_embedding(scene), basis);
  // Palette.
  auto& pal = pkg.palette;
  auto arrays = palette_arrays(scene);
  pal.names = std::move(arrays.names);
  pal.alpha_impulse = std::move(arrays.alpha_impulse);
  pal.alpha_forcing = std::move(arrays.alpha_forcing);
  pal.kinematics = std::move(arrays.kinematics);
  pal.transitions = rules.transitions;
  pal.on_end = rules.on_end;
  pal.group = rules.group;
  pal.max_in_a_row = rules.max_in_a_row;
  // Attributes.
  auto& a = pkg.attributes;
  a.scene = scene.name;
  a.dt = orbits.dt;
  a.beta = beta;
  a.blend_lambda = o.blend_lambda;
  a.eps_u = basis.eps_u;
  if (scene.view) apply_view(*scene.view, a);
  core::validate_package(pkg, scene.name);
  return out;
}

}  // namespace phasecast::precompute
