#include "test_meshes.h"

#include <Eigen/Geometry>

#include <map>
#include <numbers>
#include <utility>
#include <vector>

namespace phasecast::testing {

using precompute::TransferMesh;

namespace {

TransferMesh from_lists(const std::vector<Eigen::Vector3d>& p, const std::vector<Eigen::Vector3d>& n,
                        const std::vector<std::array<std::uint32_t, 3>>& f) {
  TransferMesh m;
  m.positions.resize(static_cast<Eigen::Index>(p.size()), 3);
  m.normals.resize(static_cast<Eigen::Index>(p.size()), 3);
  for (size_t i = 0; i < p.size(); ++i) {
    m.positions.row(static_cast<Eigen::Index>(i)) = p[i].transpose().cast<float>();
    m.normals.row(static_cast<Eigen::Index>(i)) = n[i].normalized().transpose().cast<float>();
  }
  m.triangles.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (size_t i = 0; i < f.size(); ++i) {
    for (int j = 0; j < 3; ++j) m.triangles(static_cast<Eigen::Index>(i), j) = f[i][static_cast<size_t>(j)];
  }
  return m;
}

// A grid quad patch: origin o, edge vectors u and v (u x v is the front), n x n quads.
void add_patch(std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& nrm,
               std::vector<std::array<std::uint32_t, 3>>& f, const Eigen::Vector3d& o,
               const Eigen::Vector3d& u, const Eigen::Vector3d& v, int n) {
  const auto base = static_cast<std::uint32_t>(p.size());
  const Eigen::Vector3d normal = u.cross(v).normalized();
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      p.push_back(o + u * (static_cast<double>(i) / n) + v * (static_cast<double>(j) / n));
      nrm.push_back(normal);
    }
  }
  const auto at = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      f.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      f.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
}

}  // namespace

TransferMesh icosphere(int levels) {
  const double t = (1.0 + std::sqrt(5.0)) / 2;
  std::vector<Eigen::Vector3d> p = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                    {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                    {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& x : p) x.normalize();
  std::vector<std::array<std::uint32_t, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      p.push_back((p[a] + p[b]).normalized());
      const auto id = static_cast<std::uint32_t>(p.size() - 1);
      mid.emplace(key, id);
      return id;
    };
    std::vector<std::array<std::uint32_t, 3>> next;
    for (const auto& tri : f) {
      const auto a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      next.push_back({tri[0], a, c});
      next.push_back({tri[1], b, a});
      next.push_back({tri[2], c, b});
      next.push_back({a, b, c});
    }
    f = std::move(next);
  }
  return from_lists(p, p, f);
}

TransferMesh flat_cube() {
  std::vector<Eigen::Vector3d> p, n;
  std::vector<std::array<std::uint32_t, 3>> f;
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                        Z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d c = Eigen::Vector3d::Constant(-0.5);
  add_patch(p, n, f, c, Y, X, 1);      // bottom, facing -z
  add_patch(p, n, f, c + Z, X, Y, 1);  // top, +z
  add_patch(p, n, f, c, X, Z, 1);      // front, -y
  add_patch(p, n, f, c + Y, Z, X, 1);  // back, +y
  add_patch(p, n, f, c, Z, Y, 1);      // left, -x
  add_patch(p, n, f, c + X, Y, Z, 1);  // right, +x
  return from_lists(p, n, f);
}

TransferMesh square(float half, float z, int n, bool facing_up) {
  std::vector<Eigen::Vector3d> p, nrm;
  std::vector<std::array<std::uint32_t, 3>> f;
  const Eigen::Vector3d X = 2.0 * half * Eigen::Vector3d::UnitX(), Y = 2.0 * half * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d o(-half, -half, z);
  if (facing_up) {
    add_patch(p, nrm, f, o, X, Y, n);
  } else {
    add_patch(p, nrm, f, o, Y, X, n);
  }
  return from_lists(p, nrm, f);
}

TransferMesh merge(const TransferMesh& a, const TransferMesh& b) {
  TransferMesh m;
  m.positions.resize(a.positions.rows() + b.positions.rows(), 3);
  m.positions << a.positions, b.positions;
  m.normals.resize(m.positions.rows(), 3);
  m.normals << a.normals, b.normals;
  m.triangles.resize(a.triangles.rows() + b.triangles.rows(), 3);
  m.triangles << a.triangles, (b.triangles.array() + static_cast<std::uint32_t>(a.positions.rows())).matrix();
  return m;
}

TransferMesh open_box(int n) {
  std::vector<Eigen::Vector3d> p, nrm;
  std::vector<std::array<std::uint32_t, 3>> f;
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                        Z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d c = Eigen::Vector3d::Constant(-0.5);
  add_patch(p, nrm, f, c, X, Y, n);      // floor, facing +z (inward)
  add_patch(p, nrm, f, c, Z, X, n);      // wall y = -0.5, facing +y
  add_patch(p, nrm, f, c + Y, X, Z, n);  // wall y = +0.5, facing -y
  add_patch(p, nrm, f, c, Y, Z, n);      // wall x = -0.5, facing +x
  add_patch(p, nrm, f, c + X, Z, Y, n);  // wall x = +0.5, facing -x
  return from_lists(p, nrm, f);
}

Eigen::MatrixXd furnace(const MatrixXfR& transfer) {
  const double L0 = 4 * std::numbers::pi * 0.2820947917738781;
  Eigen::MatrixXd e(transfer.rows(), 3);
  for (int c = 0; c < 3; ++c) e.col(c) = transfer.col(16 * c).cast<double>() * L0;
  return e;
}

}  // namespace phasecast::testing
