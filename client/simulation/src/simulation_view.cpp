#include "phasecast/client/simulation_view.h"

#include "phasecast/precompute/appearance/appearance_stage.h"
#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/precompute/package/package_builder.h"
#include "phasecast/precompute/sampling/orbit_store.h"
#include "phasecast/precompute/simulation/scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

namespace phasecast::client {

namespace pre = phasecast::precompute;

struct SimulationView::Impl {
  pre::Scene scene;
  pre::OrbitStore store;
  pre::Embedding embedding;
  ClientBasis rest;  // r_u = 0: mesh, flags and the rest transfer every chunk shares
};

namespace {

std::filesystem::path scene_file_of(const pre::OrbitStore& store, const std::filesystem::path& path,
                                    const std::optional<std::filesystem::path>& given) {
  if (given) return *given;
  if (store.scene_file.empty()) {
    throw std::invalid_argument(
        fmt::format("{}: the orbit store does not name the scene file that made it (expected --scene-file "
                    "scene.toml for scene '{}')",
                    path.string(), store.scene));
  }
  if (!std::filesystem::exists(store.scene_file)) {
    throw std::invalid_argument(fmt::format(
        "{}: the scene file it was made from, {}, is gone (expected --scene-file scene.toml for scene '{}')",
        path.string(), store.scene_file, store.scene));
  }
  return store.scene_file;
}

// The scene's points at rest, lit by their rest transfer, without U_u.
ClientBasis rest_basis(const pre::Scene& scene,
                       const std::function<void(const char*, long, long)>& progress) {
  const core::SceneMesh mesh = pre::scene_mesh(scene);
  // The appearance stage's transfer with the scene's rays and albedo (as
  // appearance_stage_options, without the pipeline section and its MPI).
  pre::TransferOptions transfer = pre::AppearanceStageOptions::default_stage_transfer();
  if (scene.appearance.rays > 0) transfer.rays = scene.appearance.rays;
  transfer.point_albedo = pre::scene_point_albedo(scene);
  transfer.progress = progress;
  const MatrixXfR T = pre::compute_transfer(mesh.rest_positions, mesh.triangles, mesh.normals, transfer);
  ClientBasis b;
  b.scene = scene.name;
  b.points = mesh.points();
  b.mean_shape.assign(mesh.rest_positions.data(), mesh.rest_positions.data() + mesh.rest_positions.size());
  b.triangles.assign(mesh.triangles.data(), mesh.triangles.data() + mesh.triangles.size());
  b.normals.assign(mesh.normals.data(), mesh.normals.data() + mesh.normals.size());
  b.deformable = mesh.deformable;
  b.attached = mesh.attached;
  b.mean_transfer.assign(T.data(), T.data() + T.size());
  if (scene.view) {
    core::PackageAttributes view;
    pre::apply_view(*scene.view, view);
    set_view(b, view);
  }
  return b;
}

}  // namespace

int simulation_chunk_frames(int points) {
  constexpr long kMaxBytes = 64L << 20;
  const long per_frame = 12L * std::max(points, 1);
  return static_cast<int>(std::clamp<long>(kMaxBytes / per_frame, 1, 64));
}

SimulationView::SimulationView(const std::filesystem::path& store,
                               const std::optional<std::filesystem::path>& scene_file,
                               const std::function<void(const char*, long, long)>& progress)
    : impl_(std::make_unique<Impl>()) {
  try {
    impl_->store = pre::read_orbit_store(store);
    impl_->scene = pre::load_scene_file(scene_file_of(impl_->store, store, scene_file));
    pre::check_orbit_store_matches(impl_->scene, pre::read_orbit_index(store));
  } catch (const std::exception& e) {
    const std::string what = e.what();
    throw std::invalid_argument(what.starts_with(store.string()) ? what : store.string() + ": " + what);
  }
  if (impl_->store.frames() == 0)
    throw std::invalid_argument(fmt::format("{}: the orbit store holds no frames", store.string()));
  impl_->store.velocities.resize(0, 0);  // only positions are drawn
  impl_->embedding = pre::scene_point_embedding(impl_->scene);
  impl_->rest = rest_basis(impl_->scene, progress);
}

SimulationView::~SimulationView() = default;
SimulationView::SimulationView(SimulationView&&) noexcept = default;

const std::string& SimulationView::scene() const {
  return impl_->scene.name;
}
const std::filesystem::path& SimulationView::scene_file() const {
  return impl_->scene.source;
}
double SimulationView::dt() const {
  return impl_->store.dt;
}
int SimulationView::frames() const {
  return impl_->store.frames();
}
int SimulationView::points() const {
  return impl_->rest.points;
}

int SimulationView::chunks(std::uint64_t frames) const {
  const auto n = frames > 0 ? std::min<std::uint64_t>(frames, this->frames()) : this->frames();
  const auto k = static_cast<std::uint64_t>(simulation_chunk_frames(points()));
  return static_cast<int>((n + k - 1) / k);
}

FrameChunk SimulationView::chunk(int index, std::uint64_t frames) const {
  const auto& store = impl_->store;
  const int per_chunk = simulation_chunk_frames(points());
  const int total =
      frames > 0 ? static_cast<int>(std::min<std::uint64_t>(frames, this->frames())) : this->frames();
  const int first = index * per_chunk;
  if (index < 0 || first >= total)
    throw std::out_of_range(fmt::format("chunk {} of {}", index, chunks(frames)));
  const int K = std::min(per_chunk, total - first);
  // Scene points of every frame of the chunk (3S x K) less the rest shape.
  const MatrixXfR x = store.positions.middleRows(first, K).transpose();
  MatrixXfR U = pre::embed_positions(impl_->embedding, x);
  FrameChunk c{impl_->rest, {}};
  const auto S = static_cast<Eigen::Index>(c.basis.points);
  for (Eigen::Index p = 0; p < S; ++p) {
    for (Eigen::Index i = 3 * p; i < 3 * p + 3; ++i) {
      if (c.basis.deformable[p])
        U.row(i).array() -= c.basis.mean_shape[i];
      else
        U.row(i).setZero();
    }
  }
  c.basis.rank_u = K;
  c.basis.U_u.assign(U.data(), U.data() + U.size());
  for (int k = 0; k < K; ++k) {
    FrameState f;
    f.frame = static_cast<std::uint64_t>(first + k);
    f.q_u.assign(K, 0.0f);
    f.q_u[k] = 1;
    f.support.assign(store.support.row(first + k).data(), store.support.row(first + k).data() + 12);
    c.frames.push_back(std::move(f));
  }
  return c;
}

}  // namespace phasecast::client
