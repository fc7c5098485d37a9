#pragma once
// Assembles the scene package (docs/package-format.md) from a scene, its
// palette rules, the sampled orbit store and its displacement reduction:
// scene mesh, palette, reduction, and the reduced phase portrait with
// velocities (eq. 8), beta (§2.3.2), orbit filtering and the IRF cache (§5.2).

#include "phasecast/core/package.h"
#include "phasecast/precompute/reduction/displacement_reduction.h"
#include "phasecast/precompute/reduction/phase_portrait.h"
#include "phasecast/precompute/sampling/orbit_filter.h"
#include "phasecast/precompute/sampling/palette_rules.h"
#include "phasecast/precompute/simulation/embedding.h"
#include "phasecast/precompute/simulation/scene.h"

#include <filesystem>
#include <string>
#include <vector>

namespace phasecast::precompute {

// Everything of an orbit store except its frames (read without loading them).
struct OrbitIndex {
  std::string scene;
  double dt = 0;
  int vertices = 0;
  std::vector<std::string> palette_names;
  std::vector<core::SupportKinematics> kinematics;  // per entry, as the store recorded them
  IrfList irfs;
  MatrixXfR support;  // N x 12
};

// Throws OrbitStoreError naming the file and dataset.
OrbitIndex read_orbit_index(const std::filesystem::path& store);

// The support's velocity at every node of the kept IRFs, in `kept` order
// (the IRF cache's key beside eq. 9), taken over the whole store first: a
// kept IRF's first node moves at the velocity of the IRF it continues, kept
// or not (an entry's velocity is its alpha_forcing).
std::vector<SupportVelocity> kept_support_velocities(const Scene& scene, const IrfList& irfs,
                                                     const std::vector<int>& kept);

// Throws std::invalid_argument if the orbit store does not belong to the
// scene, naming each field that differs (vertex count, palette names and
// order, a support range the store names, dt) with both values.
void check_orbit_store_matches(const Scene& scene, const OrbitIndex& orbits);

inline constexpr double kDefaultBlendLambda = 4.0;  // 1/s: an IRF blend offset halves in ~0.17 s (eq. 12)

struct PackageOptions {
  double beta = 0;  // <= 0: default beta (§2.3.2)
  double blend_lambda = kDefaultBlendLambda;
  OrbitFilterOptions filter;
};

struct PackageBuild {
  core::ScenePackage package;
  OrbitFilterResult filter;  // what was dropped and why
};

// Scene points: the render surface first (front side; render_surface.h: the
// simulated vertices of bodies without a render mesh, then the render
// meshes, at rest W X + d), then the back side of the thin sheets (a copy of
// every point of a sheet triangle, flipped normal, reversed triangles, moved
// by the same U_u rows), then every drawn box obstacle (`drawn = false`: none)
// as static points: each face
// a grid of quads of about the prop's `cell` edge (one quad when 0),
// single-sided, outward normals, its own points per face; then every prop
// mesh (a black-box simulator's drawn objects) as it came. Sheet triangles are
// the surface triangles none of whose corners moves with a vertex of a
// tetrahedron (cloth, leaves); a solid's boundary stays single-sided. Both
// sides get their own transfer (§4.1).
core::SceneMesh scene_mesh(const Scene& scene);

// How the simulated vertices move each scene point of scene_mesh(scene):
// S x V, point p at sum_i W_pi x_i + d_p (d: the rest offsets of tubes'
// rings, zero elsewhere). Back points have their front's row, static points
// none. Without render meshes every front point is its own vertex (one weight 1).
Embedding scene_point_embedding(const Scene& scene);

// Diffuse albedo (RGB) of each scene point of scene_mesh(scene): its body's
// or prop's `albedo` in the scene file (docs/scenes.md). S x 3.
MatrixXfR scene_point_albedo(const Scene& scene);

// The scene's [view] as package attributes: the camera (eye, target, up,
// fov), the floor, the light and the exposure it names.
void apply_view(const ViewSettings& view, core::PackageAttributes& attributes);

// Throws std::invalid_argument naming --beta, --blend-lambda, --dead-end-fraction, --min-irf-frames.
void check_package_options(const PackageOptions& options);

// Throws std::invalid_argument if the orbit store does not belong to the scene
// (vertex count, palette names, dt), naming both.
PackageBuild build_package(const Scene& scene, const PaletteRules& rules, const OrbitIndex& orbits,
                           const DisplacementBasis& basis, const PackageOptions& options);

}  // namespace phasecast::precompute
