#include "phasecast/precompute/simulation/scene.h"

#include "phasecast/precompute/simulation/obj_mesh.h"
#include "phasecast/precompute/simulation/scene_fields.h"
#include "phasecast/precompute/simulation/tet_mesh.h"
#include "render_mesh.h"
#include "scene_blender.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <utility>

namespace phasecast::precompute {
namespace {

using detail::Fields;
constexpr double kPi = 3.14159265358979323846;
// Quasi-static relaxation when a scene sets none: chains, simulated schedules
// and the validator all start from the same settled rest (the cloth sags, a
// toy settles onto its base) instead of an unsettled mesh.
constexpr double kDefaultSettle = 0.5;
constexpr const char* kEnergyNames = "membrane, bending, rod, tet_fem, tet_neo_hookean";

// Geometry of one body before assembly: points plus triangles, rod segments or tets.
struct BodyGeometry {
  std::vector<Eigen::Vector3d> points;
  Eigen::MatrixX3i triangles;
  std::vector<std::array<int, 2>> segments;
  Eigen::MatrixX4i tets;
  double scale = 1;  // a tetgen body's placement, shared by its render OBJ
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();
};

BodyGeometry grid_geometry(Fields grid) {
  const Eigen::Vector3d origin = grid.vec3("origin"), u = grid.vec3("u"), v = grid.vec3("v");
  const auto cells = grid.numbers("cells", 2);
  if (cells[0] < 1 || cells[1] < 1 || cells[0] != std::floor(cells[0]) || cells[1] != std::floor(cells[1])) {
    grid.fail("cells", "two positive integers");
  }
  if (u.cross(v).norm() < 1e-12) grid.fail("v", "an edge vector not parallel to u");
  grid.finish();
  const int nu = static_cast<int>(cells[0]), nv = static_cast<int>(cells[1]);
  BodyGeometry g;
  for (int j = 0; j <= nv; ++j)
    for (int i = 0; i <= nu; ++i) g.points.push_back(origin + u * i / nu + v * j / nv);
  g.triangles.resize(2 * nu * nv, 3);
  int t = 0;
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const int a = j * (nu + 1) + i, b = a + 1, c = a + nu + 1, d = c + 1;
      if ((i + j) % 2 == 0) {  // alternating diagonals keep the sheet free of a preferred shear direction
        g.triangles.row(t++) << a, b, d;
        g.triangles.row(t++) << a, d, c;
      } else {
        g.triangles.row(t++) << a, b, c;
        g.triangles.row(t++) << b, d, c;
      }
    }
  return g;
}

Eigen::MatrixX3d placed(const Eigen::MatrixX3d& v, Fields& f) {
  const double scale = f.positive("scale", 1.0);
  const Eigen::Vector3d translate = f.vec3("translate", Eigen::Vector3d::Zero());
  return (v * scale).rowwise() + translate.transpose();
}

BodyGeometry obj_geometry(Fields obj, const std::filesystem::path& dir) {
  const std::filesystem::path file = dir / obj.string("path");
  ObjMesh mesh;
  try {
    mesh = read_obj(file);
  } catch (const ObjError& e) {
    throw SceneError(fmt::format("{}: field '{}': {}", obj.file(), obj.path("path"), e.what()));
  }
  const Eigen::MatrixX3d v = placed(mesh.vertices, obj);
  obj.finish();
  BodyGeometry g;
  for (Eigen::Index i = 0; i < v.rows(); ++i) g.points.emplace_back(v.row(i).transpose());
  g.triangles = mesh.triangles;
  return g;
}

BodyGeometry polyline_geometry(Fields line) {
  const auto pts = line.points("points");
  if (pts.size() < 2) line.fail("points", "at least 2 points");
  const int sub = line.positive_integer("subdivisions", 1);
  line.finish();
  BodyGeometry g;
  g.points.push_back(pts[0]);
  for (size_t k = 1; k < pts.size(); ++k) {
    for (int s = 1; s <= sub; ++s) {
      g.points.push_back(pts[k - 1] + (pts[k] - pts[k - 1]) * s / sub);
      g.segments.push_back({static_cast<int>(g.points.size()) - 2, static_cast<int>(g.points.size()) - 1});
    }
  }
  return g;
}

BodyGeometry tetgen_geometry(Fields tg, const std::filesystem::path& dir) {
  const std::filesystem::path file = dir / tg.string("path");
  ObjMesh surface;
  try {
    surface = read_obj(file);
  } catch (const ObjError& e) {
    throw SceneError(fmt::format("{}: field '{}': {}", tg.file(), tg.path("path"), e.what()));
  }
  surface.vertices = placed(surface.vertices, tg);
  const double max_volume = tg.positive("max_volume");
  const double quality = tg.positive("radius_edge_ratio", 2.0);
  tg.finish();
  TetMesh tm;
  try {
    tm = tetrahedralize(surface, max_volume, quality);
  } catch (const std::exception& e) {
    throw SceneError(fmt::format("{}: field '{}': {}", tg.file(), tg.path("path"), e.what()));
  }
  BodyGeometry g;
  for (Eigen::Index i = 0; i < tm.vertices.rows(); ++i) g.points.emplace_back(tm.vertices.row(i).transpose());
  g.tets = tm.tets;
  g.triangles = tm.boundary;
  g.scale = tg.positive("scale", 1.0);
  g.translate = tg.vec3("translate", Eigen::Vector3d::Zero());
  return g;
}

// Edges used by more than two triangles make hinges and contact ill-defined.
void check_manifold(const Eigen::MatrixX3i& tris, Fields& body, const std::string& mesh_key) {
  std::map<std::pair<int, int>, int> uses;
  for (Eigen::Index t = 0; t < tris.rows(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = tris(t, k), b = tris(t, (k + 1) % 3);
      if (a == b) {
        throw SceneError(fmt::format("{}: field '{}': triangle {} repeats vertex {} (degenerate)",
                                     body.file(), body.path(mesh_key), t, a));
      }
      if (++uses[{std::min(a, b), std::max(a, b)}] > 2) {
        throw SceneError(
            fmt::format("{}: field '{}': non-manifold edge ({}, {}) shared by more than 2 triangles",
                        body.file(), body.path(mesh_key), std::min(a, b), std::max(a, b)));
      }
    }
  }
}

const BodyInfo& find_body(const Scene& scene, Fields& body, const std::string& key, const std::string& name) {
  for (const auto& b : scene.bodies) {
    if (b.name == name) return b;
  }
  body.fail(key, "the name of an earlier body");
}

Lame plane_stress(double young, double poisson) {
  return {young / (2 * (1 + poisson)), young * poisson / (1 - poisson * poisson)};
}

// The body's one mesh table (grid, obj, polyline or tetgen) as geometry.
BodyGeometry body_geometry(Fields& body, const std::filesystem::path& dir, std::string& mesh_key) {
  for (const char* k : {"grid", "obj", "polyline", "tetgen"}) {
    if (body.has(k)) {
      if (!mesh_key.empty()) body.fail(k, fmt::format("one mesh per body (already has '{}')", mesh_key));
      mesh_key = k;
    }
  }
  if (mesh_key.empty()) body.fail("grid", "one mesh table: grid, obj, polyline or tetgen");
  BodyGeometry g = mesh_key == "grid"       ? grid_geometry(body.table("grid"))
                   : mesh_key == "obj"      ? obj_geometry(body.table("obj"), dir)
                   : mesh_key == "polyline" ? polyline_geometry(body.table("polyline"))
                                            : tetgen_geometry(body.table("tetgen"), dir);
  if (g.triangles.rows() > 0) check_manifold(g.triangles, body, mesh_key);
  return g;
}

// Appends the body's points to the model, welding those within weld_radius
// of the named earlier body; returns each local point's model vertex.
std::vector<int> add_points(Scene& scene, Fields& body, const BodyGeometry& g) {
  std::vector<int> weld_targets;
  double weld_radius = 0;
  if (const auto weld = body.optional_string("weld_to")) {
    weld_targets = find_body(scene, body, "weld_to", *weld).vertices;
    weld_radius = body.positive("weld_radius");
  }
  DeformableModel& m = scene.model;
  std::vector<int> global(g.points.size());
  for (size_t i = 0; i < g.points.size(); ++i) {
    int match = -1;
    for (int w : weld_targets) {
      if ((m.rest.segment<3>(3 * w) - g.points[i]).norm() <= weld_radius) match = w;
    }
    if (match < 0) {
      match = m.vertices();
      m.rest.conservativeResize(m.rest.size() + 3);
      m.rest.tail<3>() = g.points[i];
      m.mass.conservativeResize(m.mass.size() + 1);
      m.mass[match] = 0;
      m.pinned.push_back(0);
    }
    global[i] = match;
  }
  return global;
}

struct Material {
  double density, young, poisson, drag;
};

Material read_material(Fields& body) {
  Material mat{};
  mat.density = body.positive("density");
  mat.young = body.positive("young");
  mat.poisson = body.number("poisson", 0.3);
  if (!(mat.poisson >= 0 && mat.poisson < 0.5)) body.fail("poisson", "a number in [0, 0.5)");
  mat.drag = body.number("drag", 0.0);
  if (mat.drag < 0) body.fail("drag", "a number >= 0");
  return mat;
}

using Gid = std::function<int(int)>;

void add_energy(DeformableModel& m, Fields& body, const std::string& e, const BodyGeometry& g,
                const Material& mat, const Gid& gid) {
  const bool triangles = g.triangles.rows() > 0 && g.tets.rows() == 0;
  if (e == "membrane" || e == "bending") {
    if (!triangles) body.fail("energies", fmt::format("'{}' only on triangle meshes (grid or obj)", e));
    if (e == "membrane") {
      for (Eigen::Index t = 0; t < g.triangles.rows(); ++t) {
        add_membrane(m, {gid(g.triangles(t, 0)), gid(g.triangles(t, 1)), gid(g.triangles(t, 2))},
                     plane_stress(mat.young, mat.poisson));
      }
    } else {
      Eigen::MatrixXi tris(g.triangles.rows(), 3);
      for (Eigen::Index t = 0; t < tris.rows(); ++t)
        for (int k = 0; k < 3; ++k) tris(t, k) = gid(g.triangles(t, k));
      const double bending = body.positive("bending");
      for (const auto& h : mesh_hinges(tris)) add_hinge(m, h, bending);
    }
  } else if (e == "rod") {
    if (g.segments.empty()) body.fail("energies", "'rod' only on polyline meshes");
    const double radius = body.positive("radius");
    const double area = kPi * radius * radius, inertia = kPi * std::pow(radius, 4) / 4;
    for (const auto& s : g.segments) add_rod_stretch(m, gid(s[0]), gid(s[1]), mat.young * area);
    for (size_t k = 0; k + 1 < g.segments.size(); ++k) {
      add_rod_bend(m, gid(g.segments[k][0]), gid(g.segments[k][1]), gid(g.segments[k + 1][1]),
                   mat.young * inertia);
    }
  } else if (e == "tet_fem" || e == "tet_neo_hookean") {
    if (g.tets.rows() == 0) body.fail("energies", fmt::format("'{}' only on tetgen meshes", e));
    const TetEnergy energy = e == "tet_fem" ? TetEnergy::corotational : TetEnergy::stable_neo_hookean;
    for (Eigen::Index t = 0; t < g.tets.rows(); ++t) {
      add_tet(m, {gid(g.tets(t, 0)), gid(g.tets(t, 1)), gid(g.tets(t, 2)), gid(g.tets(t, 3))},
              lame_from_young(mat.young, mat.poisson), energy);
    }
  } else {
    body.fail("energies", fmt::format("energy names among {} ('{}' is unknown)", kEnergyNames, e));
  }
}

// Lumped masses: each element gives its vertices equal shares of its mass;
// triangles also carry the body's air drag.
void lump_masses(DeformableModel& m, const BodyGeometry& g, const Material& mat, const Gid& gid) {
  const auto lump = [&](int v, double share) { m.mass[v] += share; };
  if (g.tets.rows() > 0) {
    for (Eigen::Index t = 0; t < g.tets.rows(); ++t) {
      Eigen::Matrix3d Dm;
      for (int k = 0; k < 3; ++k)
        Dm.col(k) =
            g.points[static_cast<size_t>(g.tets(t, k + 1))] - g.points[static_cast<size_t>(g.tets(t, 0))];
      for (int k = 0; k < 4; ++k) lump(gid(g.tets(t, k)), mat.density * std::abs(Dm.determinant()) / 24);
    }
  } else if (g.triangles.rows() > 0) {
    for (Eigen::Index t = 0; t < g.triangles.rows(); ++t) {
      const auto p = [&](int k) { return g.points[static_cast<size_t>(g.triangles(t, k))]; };
      const double area = 0.5 * (p(1) - p(0)).cross(p(2) - p(0)).norm();
      for (int k = 0; k < 3; ++k) lump(gid(g.triangles(t, k)), mat.density * area / 3);
      if (mat.drag > 0)
        m.drag.push_back(
            {{gid(g.triangles(t, 0)), gid(g.triangles(t, 1)), gid(g.triangles(t, 2))}, mat.drag});
    }
  } else {
    for (const auto& s : g.segments) {
      const double len = (g.points[static_cast<size_t>(s[1])] - g.points[static_cast<size_t>(s[0])]).norm();
      lump(gid(s[0]), mat.density * len / 2);
      lump(gid(s[1]), mat.density * len / 2);
    }
  }
}

void pin_vertices(DeformableModel& m, Fields& body, const std::vector<int>& vertices) {
  if (!body.has("pin")) return;
  Fields pin = body.table("pin");
  const Eigen::Vector3d lo = pin.vec3("min"), hi = pin.vec3("max");
  pin.finish();
  int count = 0;
  for (int v : vertices) {
    const Eigen::Vector3d p = m.rest.segment<3>(3 * v);
    if ((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all())
      m.pinned[static_cast<size_t>(v)] = 1, ++count;
  }
  if (count == 0) pin.fail("min", "a box containing at least one vertex of the body");
}

void add_body(Scene& scene, Fields body, const std::filesystem::path& dir) {
  BodyInfo info;
  info.name = body.string("name");
  info.albedo = body.albedo("albedo", kDefaultAlbedo);
  std::string mesh_key;
  const BodyGeometry g = body_geometry(body, dir, mesh_key);
  const std::vector<int> global = add_points(scene, body, g);
  info.vertices = global;
  const Gid gid = [&global](int local) { return global[static_cast<size_t>(local)]; };

  DeformableModel& m = scene.model;
  const Material mat = read_material(body);
  const auto energies = body.strings("energies");
  if (energies.empty()) body.fail("energies", fmt::format("at least one of {}", kEnergyNames));
  if (std::count(energies.begin(), energies.end(), "tet_fem") +
          std::count(energies.begin(), energies.end(), "tet_neo_hookean") >
      1)
    body.fail("energies", "one tet energy, 'tet_fem' or 'tet_neo_hookean' (each is a whole material)");
  try {
    for (const auto& e : energies) add_energy(m, body, e, g, mat, gid);
  } catch (const std::invalid_argument& e) {
    throw SceneError(fmt::format("{}: field '{}': {}", body.file(), body.path(mesh_key), e.what()));
  }
  lump_masses(m, g, mat, gid);
  pin_vertices(m, body, info.vertices);

  info.first_surface_triangle = static_cast<int>(m.surface.rows());
  info.surface_triangles = static_cast<int>(g.triangles.rows());
  m.surface.conservativeResize(m.surface.rows() + g.triangles.rows(), 3);
  for (Eigen::Index t = 0; t < g.triangles.rows(); ++t)
    for (int k = 0; k < 3; ++k) m.surface(info.first_surface_triangle + t, k) = gid(g.triangles(t, k));
  if (body.has("render")) {
    detail::SimulatedBody simulated{
        m.rest, m.surface.bottomRows(g.triangles.rows()), g.tets, g.scale, g.translate, {}, 0};
    for (Eigen::Index i = 0; i < simulated.tets.size(); ++i) simulated.tets(i) = gid(simulated.tets(i));
    for (const auto& s : g.segments) simulated.segments.push_back({gid(s[0]), gid(s[1])});
    if (!g.segments.empty() && body.has("radius")) simulated.radius = body.positive("radius");
    info.render = detail::read_render_mesh(body.table("render"), dir, simulated);
  }
  body.finish();
  scene.bodies.push_back(std::move(info));
}

// The one model vertex within `snap` of `p`: none, or two (bodies that touch
// without a weld), is an error naming the point.
int snapped_vertex(const DeformableModel& m, Fields& brace, const std::string& key, const Eigen::Vector3d& p,
                   double snap) {
  const auto point = fmt::format("[{:g}, {:g}, {:g}]", p.x(), p.y(), p.z());
  int found = -1;
  double nearest = std::numeric_limits<double>::infinity();
  for (int v = 0; v < m.vertices(); ++v) {
    const double d = (m.rest.segment<3>(3 * v) - p).norm();
    nearest = std::min(nearest, d);
    if (d > snap) continue;
    if (found >= 0)
      brace.fail(key,
                 fmt::format("a point near one vertex ({} is within snap = {:g} m of vertices {} and {})",
                             point, snap, found, v));
    found = v;
  }
  if (found < 0)
    brace.fail(key,
               fmt::format("points within snap = {:g} m of a body's vertex ({} is {:.3g} m from the nearest)",
                           snap, point, nearest));
  return found;
}

// [[brace]]: axial springs from one vertex to others, anchoring a weld's joint
// against turning (a rod carries no twist, and a weld alone is a ball joint).
void add_braces(DeformableModel& m, Fields brace) {
  const double snap = brace.positive("snap", 1e-4);
  const int from = snapped_vertex(m, brace, "from", brace.vec3("from"), snap);
  const auto to = brace.points("to");
  if (to.empty()) brace.fail("to", "at least one point");
  const double ea = brace.positive("ea");
  std::vector<int> ends;
  for (const auto& p : to) {
    const int v = snapped_vertex(m, brace, "to", p, snap);
    if (v == from) brace.fail("to", "points at other vertices than 'from'");
    if (std::find(ends.begin(), ends.end(), v) != ends.end()) brace.fail("to", "points at distinct vertices");
    ends.push_back(v);
    add_brace(m, from, v, ea);
  }
  brace.finish();
}

// [simulation] integrator, and Newmark's gamma and beta, held to the
// unconditionally stable part of the family.
void read_integrator(Fields& sim, SimulationSettings& s) {
  const std::string integrator = sim.optional_string("integrator").value_or("backward_euler");
  if (integrator != "backward_euler" && integrator != "newmark")
    sim.fail("integrator", "\"backward_euler\" or \"newmark\"");
  if (integrator == "backward_euler") {
    for (const char* key : {"newmark_gamma", "newmark_beta"})
      if (sim.has(key)) sim.fail(key, "no value unless integrator = \"newmark\"");
    return;
  }
  s.integrator = Integrator::newmark;
  s.newmark_gamma = sim.number("newmark_gamma", s.newmark_gamma);
  if (!(s.newmark_gamma >= 0.5)) sim.fail("newmark_gamma", "a number >= 0.5");
  const double least_beta = (s.newmark_gamma + 0.5) * (s.newmark_gamma + 0.5) / 4;
  s.newmark_beta = sim.number("newmark_beta", least_beta);  // 1/4 for the trapezoidal rule
  if (!(s.newmark_beta >= least_beta))
    sim.fail("newmark_beta", fmt::format("a number >= (newmark_gamma + 1/2)^2 / 4 = {}", least_beta));
}

SimulationSettings read_simulation(Fields sim) {
  SimulationSettings s;
  s.frame_dt = sim.positive("frame_dt");
  s.substeps = sim.positive_integer("substeps", s.substeps);
  s.newton_iterations = sim.positive_integer("newton_iterations", s.newton_iterations);
  s.newton_tolerance = sim.positive("newton_tolerance", s.newton_tolerance);
  s.gravity = sim.vec3("gravity", s.gravity);
  s.mass_damping = sim.number("mass_damping", 0);
  s.stiffness_damping = sim.number("stiffness_damping", 0);
  if (s.mass_damping < 0) sim.fail("mass_damping", "a number >= 0");
  if (s.stiffness_damping < 0) sim.fail("stiffness_damping", "a number >= 0");
  s.max_speed = sim.positive("max_speed", s.max_speed);
  s.friction = sim.number("friction", s.friction);
  if (s.friction < 0 || s.friction > 1) sim.fail("friction", "a number in [0, 1]");
  s.settle = sim.number("settle", kDefaultSettle);
  if (s.settle < 0) sim.fail("settle", "a number >= 0");
  if (sim.has("linear_solver")) {
    const std::string solver = sim.string("linear_solver");
    if (solver != "simplicial" && solver != "supernodal")
      sim.fail("linear_solver", "\"simplicial\" or \"supernodal\"");
    s.linear_solver = solver == "supernodal" ? LinearSolver::supernodal : LinearSolver::simplicial;
  }
  read_integrator(sim, s);
  sim.finish();
  return s;
}

SupportSettings read_support(Fields sup) {
  SupportSettings s;
  const std::string motion = sup.string("motion");
  if (motion != "rotational" && motion != "translational")
    sup.fail("motion", "\"rotational\" or \"translational\"");
  s.rotational = motion == "rotational";
  s.axis = sup.vec3("axis");
  if (s.axis.norm() < 1e-12) sup.fail("axis", "a non-zero vector");
  s.axis.normalize();
  s.pivot = sup.vec3("pivot", Eigen::Vector3d::Zero());
  if (sup.has("range")) {
    const auto r = sup.numbers("range", 2);
    if (!(r[0] < r[1])) sup.fail("range", "[min, max] with min < max");
    const double unit = s.rotational ? kPi / 180 : 1.0;  // degrees for rotational supports
    s.range_min = r[0] * unit;
    s.range_max = r[1] * unit;
  }
  s.pulse_tau = sup.number("pulse_tau", 0);
  if (s.pulse_tau < 0) sup.fail("pulse_tau", "a number >= 0");
  sup.finish();
  return s;
}

AppearanceDefaults read_appearance_defaults(Fields a) {
  AppearanceDefaults d;
  d.clusters = a.positive_integer("clusters", 0);
  d.eps_a = a.number("eps_a", 0);
  if (a.has("eps_a") && !(d.eps_a > 0 && d.eps_a < 1)) a.fail("eps_a", "a number in (0, 1)");
  d.held_out = a.positive_integer("held_out", 0);
  d.rays = a.positive_integer("rays", 0);
  d.paper_rank_a = a.positive_integer("paper_rank_a", 0);
  a.finish();
  return d;
}

PaletteEntry read_entry(Fields e, const Scene& scene) {
  PaletteEntry p;
  p.name = e.string("name");
  if (p.name.empty()) e.fail("name", "a non-empty name");
  for (const auto& other : scene.palette) {
    if (other.name == p.name) e.fail("name", "a name not used by an earlier entry");
  }
  p.alpha_impulse = e.vec3("alpha_impulse");
  p.alpha_forcing = e.vec3("alpha_forcing");
  // A rotating support turns about its one axis: angular velocities must lie along it.
  if (scene.support.rotational) {
    for (const char* key : {"alpha_impulse", "alpha_forcing"}) {
      const Eigen::Vector3d a = std::string(key) == "alpha_impulse" ? p.alpha_impulse : p.alpha_forcing;
      if (a.cross(scene.support.axis).norm() > 1e-9 * (1 + a.norm()))
        e.fail(key, "an angular velocity along support.axis");
    }
  }
  if (e.has("after")) p.after = e.strings("after");
  p.t_min = e.number("t_min", p.t_min);
  p.t_max = e.positive("t_max", p.t_max);
  if (!(p.t_min >= 0 && p.t_min < p.t_max)) e.fail("t_min", "a number >= 0 and below t_max");
  p.on_end = e.optional_string("on_end").value_or(p.on_end);
  p.group = e.optional_string("group").value_or(p.name);
  const double run = e.number("max_in_a_row", 0);
  if (!(run >= 0 && run <= 1e6 && run == std::floor(run))) e.fail("max_in_a_row", "a whole number >= 0");
  p.max_in_a_row = static_cast<int>(run);
  e.finish();
  return p;
}

DemoDefaults read_demo(Fields d, const std::filesystem::path& folder) {
  DemoDefaults demo;
  // Not required to exist: precompute never runs it, and a scene copied
  // elsewhere as a template still loads (scripts/demo checks the file).
  demo.script = std::filesystem::absolute(folder / d.string("script")).lexically_normal();
  const double seed = d.number("seed", demo.seed);
  if (!(seed >= 0 && seed <= 1e9 && seed == std::floor(seed))) d.fail("seed", "a whole number >= 0");
  demo.seed = static_cast<int>(seed);
  d.finish();
  return demo;
}

ViewSettings read_view(Fields v) {
  ViewSettings view;
  if (v.has("eye") != v.has("target")) v.fail(v.has("eye") ? "target" : "eye", "eye and target together");
  if (v.has("eye")) {
    view.eye = v.vec3("eye");
    view.target = v.vec3("target");
    if (!((*view.eye - *view.target).norm() > 0)) v.fail("target", "a point other than eye");
  }
  for (const char* key : {"up", "fov"}) {
    if (v.has(key) && !view.eye) v.fail(key, "eye and target with it (they make the camera together)");
  }
  view.up = v.vec3("up", view.up);
  view.fov_y_deg = v.number("fov", view.fov_y_deg);
  if (!(view.fov_y_deg > 0 && view.fov_y_deg < 180))
    v.fail("fov", "a vertical field of view in (0, 180) degrees");
  if (view.eye && !((*view.target - *view.eye).normalized().cross(view.up).norm() > 1e-6))
    v.fail("up", "a vector across the view direction");
  if (v.is_string("floor")) {
    if (v.string("floor") != "none") v.fail("floor", "a height (y, m) or \"none\"");
    view.floor = false;
  } else if (v.has("floor")) {
    view.floor_height = v.number("floor");
  }
  if (v.has("light")) {
    view.light = v.string("light");
    if (std::ranges::find(core::kLightProbeNames, view.light) == core::kLightProbeNames.end())
      v.fail("light", fmt::format("one of {}", fmt::join(core::kLightProbeNames, ", ")));
  }
  if (v.has("exposure")) view.exposure = v.positive("exposure");
  v.finish();
  return view;
}

// [simulation], [support], [contact], bodies, braces and obstacles: the
// model the built-in simulator integrates.
void read_builtin_model(Fields& top, Scene& scene) {
  scene.simulation = read_simulation(top.table("simulation"));
  scene.support = read_support(top.table("support"));
  if (top.has("contact")) {
    Fields contact = top.table("contact");
    scene.model.thickness = contact.positive("thickness", scene.model.thickness);
    scene.model.self_collision = contact.flag("self_collision", scene.model.self_collision);
    scene.model.self_friction = contact.number("friction", scene.model.self_friction);
    if (!(scene.model.self_friction >= 0)) contact.fail("friction", "a Coulomb coefficient >= 0");
    if (scene.model.self_friction > 0 && !scene.model.self_collision)
      contact.fail("friction", "0 without self_collision = true (it acts between surfaces in self-contact)");
    scene.model.incremental_ccd = contact.flag("incremental_ccd", scene.model.incremental_ccd);
    contact.finish();
  }
  auto bodies = top.tables("body");
  if (bodies.empty()) top.fail("body", "at least one [[body]]");
  for (auto& b : bodies) add_body(scene, b, scene.source.parent_path());
  for (auto& b : top.tables("brace")) add_braces(scene.model, b);
  for (auto& o : top.tables("obstacle")) {
    BoxObstacle box{o.string("name"), o.vec3("min"), o.vec3("max")};
    if (!(box.min.array() < box.max.array()).all()) o.fail("max", "a corner above min on every axis");
    PropLook look{o.albedo("albedo", kDefaultAlbedo), o.number("cell", 0)};
    if (!(look.cell >= 0)) o.fail("cell", "a tessellation edge length >= 0 (m)");
    if (look.cell > 0 && (box.max - box.min).maxCoeff() / look.cell > kMaxPropCells)
      o.fail("cell", fmt::format("at most {} cells along an edge of the box", kMaxPropCells));
    look.drawn = o.flag("drawn", look.drawn);
    o.finish();
    scene.model.obstacles.push_back(box);
    scene.props.push_back(look);
  }
  for (int v = 0; v < scene.model.vertices(); ++v) {
    if (!(scene.model.mass[v] > 0)) {
      throw SceneError(fmt::format(
          "{}: vertex {} belongs to no element and has no mass (unused mesh vertex?)", top.file(), v));
    }
  }
}

std::string simulator_kind(Fields& top) {
  if (!top.has("simulator")) return "builtin";
  Fields sim = top.table("simulator");
  const std::string kind = sim.optional_string("kind").value_or("builtin");
  if (kind != "builtin" && kind != "blender") sim.fail("kind", "\"builtin\" or \"blender\"");
  if (kind == "builtin") sim.finish();
  return kind;
}

}  // namespace

int Scene::palette_index(const std::string& entry) const {
  std::string known;
  for (size_t i = 0; i < palette.size(); ++i) {
    if (palette[i].name == entry) return static_cast<int>(i);
    known += (i ? ", " : "") + palette[i].name;
  }
  throw SceneError(
      fmt::format("{}: unknown palette entry '{}' (expected one of: {})", source.string(), entry, known));
}

Scene load_scene_file(const std::filesystem::path& path) {
  toml::table root;
  try {
    root = toml::parse_file(path.string());
  } catch (const toml::parse_error& e) {
    throw SceneError(fmt::format("{}:{}:{}: {}", path.string(), e.source().begin.line,
                                 e.source().begin.column, e.description()));
  }
  Fields top(root, path.string(), "");
  Scene scene;
  scene.source = path;
  scene.name = top.string("name");
  if (simulator_kind(top) == "blender") {
    scene.simulation = detail::read_blender_simulation(top.table("simulation"), kDefaultSettle);
    scene.support = read_support(top.table("support"));
    detail::read_blender_model(top, scene);
  } else {
    read_builtin_model(top, scene);
  }
  auto entries = top.tables("palette");
  if (entries.empty()) top.fail("palette", "at least one [[palette]] entry");
  for (auto& e : entries) scene.palette.push_back(read_entry(e, scene));
  if (top.has("appearance")) scene.appearance = read_appearance_defaults(top.table("appearance"));
  if (top.has("validation")) {
    Fields v = top.table("validation");
    scene.standard_schedule = v.string("schedule");
    v.finish();
  }
  if (top.has("demo")) scene.demo = read_demo(top.table("demo"), path.parent_path());
  if (top.has("view")) scene.view = read_view(top.table("view"));
  top.finish();
  return scene;
}

core::SupportKinematics entry_kinematics(const Scene& scene, int entry) {
  const auto& e = scene.palette.at(static_cast<size_t>(entry));
  const auto& s = scene.support;
  core::SupportKinematics k;
  k.rotational = s.rotational;
  k.pivot = {static_cast<float>(s.pivot.x()), static_cast<float>(s.pivot.y()),
             static_cast<float>(s.pivot.z())};
  k.range_min = static_cast<float>(s.range_min);
  k.range_max = static_cast<float>(s.range_max);
  k.pulse_tau = static_cast<float>(s.pulse_tau);
  // Jolts are described by their impulse, held motions by their forcing.
  const Eigen::Vector3d alpha = s.pulse_tau > 0 ? e.alpha_impulse : e.alpha_forcing;
  Eigen::Vector3d axis = s.axis;
  double rate = alpha.dot(s.axis);
  if (alpha.cross(s.axis).norm() > 1e-9 * (1 + alpha.norm())) {
    axis = alpha.normalized();
    rate = alpha.norm();
  }
  k.axis = {static_cast<float>(axis.x()), static_cast<float>(axis.y()), static_cast<float>(axis.z())};
  k.rate = static_cast<float>(rate);
  return k;
}

std::unique_ptr<Simulator> make_simulator(const Scene& scene) {
  if (scene.blender)
    return make_blender_simulator(*scene.blender, scene.simulation.frame_dt, scene.support, scene.model.rest);
  return make_implicit_simulator(scene.model, scene.simulation, scene.support);
}

}  // namespace phasecast::precompute
