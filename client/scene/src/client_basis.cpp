#include "phasecast/client/client_basis.h"

#include "phasecast/core/package.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace phasecast::client {
namespace {

template <class T>
std::vector<T> copy_of(const T* data, Eigen::Index count) {
  return std::vector<T>(data, data + count);
}

void expect_size(const std::string& source, const char* part, std::size_t actual, std::size_t expected,
                 const std::string& how) {
  if (actual != expected) {
    throw std::invalid_argument(fmt::format("{}: basis part {} has {} values (expected {} = {})", source,
                                            part, actual, expected, how));
  }
}

void expect_finite(const std::string& source, const char* part, const std::vector<float>& values) {
  const auto bad = std::find_if(values.begin(), values.end(), [](float v) { return !std::isfinite(v); });
  if (bad != values.end()) {
    throw std::invalid_argument(
        fmt::format("{}: basis part {} has a non-finite value {} at index {} (expected "
                    "finite float32)",
                    source, part, *bad, bad - values.begin()));
  }
}

}  // namespace

void ClientBasis::validate(const std::string& source) const {
  if (points <= 0)
    throw std::invalid_argument(fmt::format("{}: scene has {} points (expected S > 0)", source, points));
  if (rank_u < 0 || rank_a < 0) {
    throw std::invalid_argument(
        fmt::format("{}: ranks r_u = {}, r_a = {} (expected >= 0)", source, rank_u, rank_a));
  }
  const auto S = static_cast<std::size_t>(points);
  expect_size(source, "mean_shape", mean_shape.size(), 3 * S, "3S");
  expect_size(source, "normals", normals.size(), 3 * S, "3S");
  expect_size(source, "deformable", deformable.size(), S, "S");
  expect_size(source, "attached", attached.size(), S, "S");
  expect_size(source, "U_u", U_u.size(), 3 * S * static_cast<std::size_t>(rank_u), "3S x r_u");
  if (triangles.empty() || triangles.size() % 3 != 0) {
    throw std::invalid_argument(
        fmt::format("{}: basis part triangles has {} indices (expected a positive "
                    "multiple of 3)",
                    source, triangles.size()));
  }
  const auto worst = *std::max_element(triangles.begin(), triangles.end());
  if (worst >= S) {
    throw std::invalid_argument(fmt::format(
        "{}: basis part triangles refers to point {} (expected indices < S = {})", source, worst, S));
  }
  if (has_transfer()) {
    expect_size(source, "mean_transfer", mean_transfer.size(), core::kTransferPerPoint * S, "48S");
    expect_size(source, "U_a", U_a.size(), core::kTransferPerPoint * S * static_cast<std::size_t>(rank_a),
                "48S x r_a");
  } else if (rank_a != 0) {
    throw std::invalid_argument(fmt::format(
        "{}: r_a = {} but basis part mean_transfer is missing (expected 48S values)", source, rank_a));
  }
  expect_finite(source, "mean_shape", mean_shape);
  expect_finite(source, "normals", normals);
  expect_finite(source, "U_u", U_u);
  expect_finite(source, "mean_transfer", mean_transfer);
  expect_finite(source, "U_a", U_a);
}

ClientBasis basis_from_package(const core::ScenePackage& p, std::uint64_t content_hash) {
  ClientBasis b;
  b.scene = p.attributes.scene;
  b.content_hash = content_hash;
  b.points = p.mesh.points();
  b.rank_u = p.rank_u();
  b.rank_a = p.rank_a();
  b.mean_shape = copy_of(p.reduction.mean_shape.data(), p.reduction.mean_shape.size());
  b.triangles = copy_of(p.mesh.triangles.data(), p.mesh.triangles.size());
  b.normals = copy_of(p.mesh.normals.data(), p.mesh.normals.size());
  b.deformable = p.mesh.deformable;
  b.attached = p.mesh.attached;
  b.U_u = copy_of(p.reduction.U_u.data(), p.reduction.U_u.size());
  if (p.appearance) {
    b.mean_transfer = copy_of(p.appearance->mean_transfer.data(), p.appearance->mean_transfer.size());
    b.U_a = copy_of(p.appearance->U_a.data(), p.appearance->U_a.size());
  }
  set_view(b, p.attributes);
  return b;
}

void set_view(ClientBasis& b, const core::PackageAttributes& a) {
  b.camera = a.camera;
  b.floor = a.floor;
  b.floor_height = a.floor_height;
  b.light = a.light;
  b.exposure = a.exposure;
}

std::vector<double> cpu_positions(const ClientBasis& b, const std::vector<float>& q_u,
                                  const std::vector<float>& support) {
  std::vector<double> x(b.mean_shape.begin(), b.mean_shape.end());
  const auto r = static_cast<std::size_t>(b.rank_u);
  for (std::size_t v = 0; v < static_cast<std::size_t>(b.points); ++v) {
    if (b.deformable[v]) {
      for (std::size_t c = 0; c < 3; ++c) {
        for (std::size_t j = 0; j < r; ++j) x[3 * v + c] += double(b.U_u[(3 * v + c) * r + j]) * q_u[j];
      }
    }
    if (b.attached[v] && support.size() == 12) {
      const double p[3] = {x[3 * v], x[3 * v + 1], x[3 * v + 2]};
      for (std::size_t i = 0; i < 3; ++i) {
        x[3 * v + i] = support[4 * i] * p[0] + support[4 * i + 1] * p[1] + support[4 * i + 2] * p[2] +
                       double(support[4 * i + 3]);
      }
    }
  }
  return x;
}

}  // namespace phasecast::client
