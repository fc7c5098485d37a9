#include "phasecast/precompute/sampling/obj_frames.h"

#include "phasecast/precompute/simulation/obj_mesh.h"

#include <fmt/format.h>

namespace phasecast::precompute {
namespace {

void append_box(const BoxObstacle& box, Eigen::MatrixX3d& v, Eigen::MatrixX3i& f) {
  const Eigen::Index base = v.rows();
  v.conservativeResize(base + 8, 3);
  for (int c = 0; c < 8; ++c) {
    v.row(base + c) << (c & 1 ? box.max.x() : box.min.x()), (c & 2 ? box.max.y() : box.min.y()),
        (c & 4 ? box.max.z() : box.min.z());
  }
  // Outward-facing quads of the corner numbering above, two triangles each.
  static constexpr int kQuads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                       {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  const Eigen::Index t = f.rows();
  f.conservativeResize(t + 12, 3);
  for (int q = 0; q < 6; ++q) {
    const auto i = [&](int k) { return static_cast<int>(base) + kQuads[q][k]; };
    f.row(t + 2 * q) << i(0), i(1), i(2);
    f.row(t + 2 * q + 1) << i(0), i(2), i(3);
  }
}

void append_mesh(const PropMesh& mesh, Eigen::MatrixX3d& v, Eigen::MatrixX3i& f) {
  const Eigen::Index base = v.rows(), t = f.rows();
  v.conservativeResize(base + mesh.positions.rows(), 3);
  v.bottomRows(mesh.positions.rows()) = mesh.positions;
  f.conservativeResize(t + mesh.triangles.rows(), 3);
  f.bottomRows(mesh.triangles.rows()) = mesh.triangles.array() + static_cast<int>(base);
}

}  // namespace

int write_obj_frames(const OrbitStore& store, const std::vector<BoxObstacle>& obstacles,
                     const std::vector<PropMesh>& meshes, const std::filesystem::path& dir,
                     const std::function<void(int, int)>& progress) {
  std::filesystem::create_directories(dir);
  const int V = store.vertices();
  for (int n = 0; n < store.frames(); ++n) {
    Eigen::MatrixX3d v(V, 3);
    for (int i = 0; i < V; ++i) v.row(i) = store.positions.block(n, 3 * i, 1, 3).cast<double>();
    Eigen::MatrixX3i f = store.triangles.cast<int>();
    for (const auto& box : obstacles) append_box(box, v, f);
    for (const auto& mesh : meshes) append_mesh(mesh, v, f);
    const Eigen::Matrix<double, 3, 4, Eigen::RowMajor> T =
        Eigen::Map<const Eigen::Matrix<float, 3, 4, Eigen::RowMajor>>(store.support.row(n).data())
            .cast<double>();
    const Eigen::MatrixX3d world = (v * T.leftCols<3>().transpose()).rowwise() + T.col(3).transpose();
    write_obj(dir / fmt::format("frame_{:05d}.obj", n), world, f, store.segments.cast<int>());
    if (progress) progress(n + 1, store.frames());
  }
  return store.frames();
}

}  // namespace phasecast::precompute
