#include "synthetic_package.h"

#include "phasecast/core/dense_svd.h"
#include "phasecast/core/sh.h"

#include <Eigen/Dense>
#include <Eigen/QR>

#include <cmath>
#include <numbers>
#include <random>

namespace phasecast::testing {
namespace {

using core::ScenePackage;
constexpr double kPi = std::numbers::pi;
constexpr float kOmega0 = static_cast<float>(kPi / 4);  // door speed, rad/s

// Plate points on [0,1]^2 at z = 0 (top row pinned to the door, y = 1), then
// the four corners of the static door board behind it.
void build_mesh(ScenePackage& p, int n) {
  const int plate = n * n;
  const int S = plate + 4;
  auto& m = p.mesh;
  m.rest_positions.resize(S, 3);
  m.normals.resize(S, 3);
  m.deformable.assign(static_cast<size_t>(S), 1);
  m.attached.assign(static_cast<size_t>(S), 1);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int v = j * n + i;
      m.rest_positions.row(v) << static_cast<float>(i) / static_cast<float>(n - 1),
          static_cast<float>(j) / static_cast<float>(n - 1), 0.0f;
      if (j == n - 1) m.deformable[static_cast<size_t>(v)] = 0;  // pinned row
    }
  }
  const float board[4][2] = {{-0.1f, -0.1f}, {1.1f, -0.1f}, {1.1f, 1.1f}, {-0.1f, 1.1f}};
  for (int c = 0; c < 4; ++c) {
    m.rest_positions.row(plate + c) << board[c][0], board[c][1], -0.05f;
    m.deformable[static_cast<size_t>(plate + c)] = 0;
  }
  m.normals.setZero();
  m.normals.col(2).setOnes();
  m.triangles.resize(2 * (n - 1) * (n - 1) + 2, 3);
  int t = 0;
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const auto a = static_cast<std::uint32_t>(j * n + i);
      const auto b = a + 1, c = a + static_cast<std::uint32_t>(n), d = c + 1;
      m.triangles.row(t++) << a, b, d;
      m.triangles.row(t++) << a, d, c;
    }
  }
  const auto b0 = static_cast<std::uint32_t>(plate);
  m.triangles.row(t++) << b0, b0 + 1, b0 + 2;
  m.triangles.row(t++) << b0, b0 + 2, b0 + 3;
}

// Cantilever-like modes hanging from the top edge: out-of-plane bending in
// (1 - y) times a cosine across x, orthonormalised by QR.
MatrixXfR plate_modes(const ScenePackage& p, int r) {
  const auto& m = p.mesh;
  Eigen::MatrixXd U = Eigen::MatrixXd::Zero(3 * m.points(), r);
  for (int v = 0; v < m.points(); ++v) {
    if (!m.deformable[static_cast<size_t>(v)]) continue;
    const double x = m.rest_positions(v, 0), s = 1.0 - m.rest_positions(v, 1);
    for (int k = 0; k < r; ++k) {
      const int along = k / 2 + 1, across = k % 2;
      U(3 * v + 2, k) = std::sin((along - 0.5) * kPi * s) * std::cos(across * kPi * x);
      U(3 * v + 0, k) = 0.1 * across * std::sin(kPi * s) * std::sin(kPi * x);  // some in-plane sway
    }
  }
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(U);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(U.rows(), r);
  return Q.cast<float>();
}

void build_palette(ScenePackage& p) {
  auto& pal = p.palette;
  pal.names = {"close", "stop", "open"};
  pal.alpha_impulse.resize(3, 1);
  pal.alpha_impulse << -kOmega0, 0.0f, kOmega0;
  pal.alpha_forcing = pal.alpha_impulse;  // door: alpha^I = alpha^F (§3.3)
  pal.transitions.resize(4, 3);
  pal.transitions << 1, 0, 1,           // from rest: close or open
      0, 1, 0,                          // from close: stop
      1, 0, 1,                          // from stop: close or open
      0, 1, 0;                          // from open: stop
  pal.on_end = {1, core::kEndRest, 1};  // the door stops at the end of its range
  pal.group = {0, 1, 2};
  pal.max_in_a_row = {0, 0, 0};
  for (int d = 0; d < 3; ++d) {
    core::SupportKinematics k;
    k.axis = {0, 1, 0};
    k.pivot = {0, 0, -0.05f};
    k.rotational = true;
    k.rate = pal.alpha_forcing(d, 0);
    k.range_min = 0;
    k.range_max = static_cast<float>(kPi / 2);
    pal.kinematics.push_back(k);
  }
}

// Damped oscillations about an entry-dependent offset (the persistent
// forcing of an opening or closing door pushes the cloth one way).
void build_irfs(ScenePackage& p, const PlateOptions& o) {
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> phase(0, 2 * kPi), amp(0.5, 1.0);
  const int D = p.palette.size(), r = o.rank_u;
  const int N = D * o.irfs_per_entry * o.irf_length;
  auto& pp = p.portrait;
  pp.q_u.resize(N, r);
  pp.support.resize(N, core::kSupportFloats);
  int node = 0;
  for (int d = 0; d < D; ++d) {
    for (int i = 0; i < o.irfs_per_entry; ++i) {
      pp.irf_start.push_back(node);
      pp.irf_length.push_back(o.irf_length);
      pp.irf_palette.push_back(d);
      const double a = amp(rng), ph = phase(rng), forcing = 0.15 * (d - 1);
      for (int t = 0; t < o.irf_length; ++t, ++node) {
        const double time = t * o.dt;
        for (int k = 0; k < r; ++k) {
          const double omega = 2 * kPi * (0.8 + 0.9 * k), decay = 1.5 + 0.5 * k;
          const double value = a / (k + 1) * 0.2 * std::exp(-decay * time) * std::cos(omega * time + ph + k);
          pp.q_u(node, k) = static_cast<float>(value + (k == 0 ? forcing : 0.0));
        }
        const double angle = std::clamp(0.6 + (d - 1) * kOmega0 * time, 0.0, kPi / 2);
        const float c = static_cast<float>(std::cos(angle)), s = static_cast<float>(std::sin(angle));
        pp.support.row(node) << c, 0, s, 0, 0, 1, 0, 0, -s, 0, c, 0;
      }
    }
  }
}

// Rotate the modes onto the principal axes of the data and centre it, so that
// Q_u = S V^T (eq. 6) holds exactly and the singular values are the data's.
void principal_axes(ScenePackage& p, const MatrixXfR& modes) {
  auto& q = p.portrait.q_u;
  const Eigen::RowVectorXf mean = q.colwise().mean();
  q.rowwise() -= mean;
  p.reduction.mean_shape = VectorXf(3 * p.mesh.points());
  Eigen::Map<MatrixXfR>(p.reduction.mean_shape.data(), p.mesh.points(), 3) = p.mesh.rest_positions;
  p.reduction.mean_shape += modes * mean.transpose();

  const core::DenseSvd svd = core::dense_svd(q.cast<double>(), core::SvdVectors::right);
  const Eigen::MatrixXf W = svd.V.cast<float>();
  q = q * W;
  p.reduction.U_u = modes * W;
  p.reduction.singular_values = svd.sigma.cast<float>();
  const double total = svd.sigma.squaredNorm();
  p.reduction.rel_error.resize(p.reduction.singular_values.size());
  double kept = 0;
  for (Eigen::Index i = 0; i < p.reduction.rel_error.size(); ++i) {
    kept += std::pow(svd.sigma[i], 2);
    p.reduction.rel_error[i] = static_cast<float>(std::sqrt(std::max(0.0, total - kept) / total));
  }
}

// Eq. 8: forward differences inside an IRF, backward at its last node.
void velocities_and_cache(ScenePackage& p) {
  auto& pp = p.portrait;
  const float dt = static_cast<float>(p.attributes.dt);
  pp.qdot_u.resizeLike(pp.q_u);
  for (int i = 0; i < pp.irf_count(); ++i) {
    const int s = pp.irf_start[static_cast<size_t>(i)], n = pp.irf_length[static_cast<size_t>(i)];
    for (int t = 0; t < n; ++t) {
      const int k = s + t;
      pp.qdot_u.row(k) =
          t + 1 < n ? (pp.q_u.row(k + 1) - pp.q_u.row(k)) / dt : (pp.q_u.row(k) - pp.q_u.row(k - 1)) / dt;
    }
  }
  const double max_q = pp.q_u.rowwise().squaredNorm().maxCoeff();
  const double max_v = pp.qdot_u.rowwise().squaredNorm().maxCoeff();
  p.attributes.beta = max_v > 0 ? max_q / max_v : 1.0;  // §2.3.2 default

  const int N = pp.nodes(), D = p.palette.size();
  pp.nearest_irf.setConstant(N, D, -1);
  const auto beta = static_cast<float>(p.attributes.beta);
  for (int j = 0; j < N; ++j) {
    Eigen::VectorXf best = Eigen::VectorXf::Constant(D, INFINITY);
    for (int i = 0; i < pp.irf_count(); ++i) {
      const int s = pp.irf_start[static_cast<size_t>(i)], d = pp.irf_palette[static_cast<size_t>(i)];
      const float dist = (pp.q_u.row(j) - pp.q_u.row(s)).squaredNorm() +
                         beta * (pp.qdot_u.row(j) - pp.qdot_u.row(s)).squaredNorm();
      if (dist < best[d]) {
        best[d] = dist;
        pp.nearest_irf(j, d) = i;
      }
    }
  }
}

MatrixXfR deformed_normals(const ScenePackage& p, const Eigen::VectorXf& x) {
  const int S = p.mesh.points();
  MatrixXfR n = MatrixXfR::Zero(S, 3);
  for (Eigen::Index t = 0; t < p.mesh.triangles.rows(); ++t) {
    const auto a = p.mesh.triangles(t, 0), b = p.mesh.triangles(t, 1), c = p.mesh.triangles(t, 2);
    const Eigen::Vector3f pa = x.segment<3>(3 * a), pb = x.segment<3>(3 * b), pc = x.segment<3>(3 * c);
    const Eigen::Vector3f fn = (pb - pa).cross(pc - pa);
    for (const auto v : {a, b, c}) {
      for (int i = 0; i < 3; ++i) n(v, i) += fn[i];
    }
  }
  n.rowwise().normalize();
  return n;
}

// Unshadowed diffuse transfer (ρ/π)·Â_l·Y_k(n) per point and channel (§4.1).
Eigen::VectorXf unshadowed_transfer(const MatrixXfR& normals) {
  const float albedo[3] = {0.8f, 0.3f, 0.25f};
  Eigen::VectorXf M(core::kTransferPerPoint * normals.rows());
  for (Eigen::Index v = 0; v < normals.rows(); ++v) {
    const auto y = core::sh_basis(normals(v, 0), normals(v, 1), normals(v, 2));
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 16; ++k) {
        M[48 * v + 16 * c + k] =
            static_cast<float>(albedo[c] / kPi * core::clamped_cosine_band(core::sh_band(k))) *
            y[static_cast<size_t>(k)];
      }
    }
  }
  return M;
}

void fit_appearance_model(ScenePackage& p, const PlateOptions& o) {
  const auto& pp = p.portrait;
  const int N = pp.nodes(), Na = std::min(o.clusters, N);
  core::Appearance a;
  Eigen::MatrixXd A(core::kTransferPerPoint * p.mesh.points(), Na);
  for (int j = 0; j < Na; ++j) {
    const int node = static_cast<int>(static_cast<long>(j) * N / Na);
    a.cluster_nodes.push_back(node);
    const Eigen::VectorXf x = p.reduction.mean_shape + p.reduction.U_u * pp.q_u.row(node).transpose();
    A.col(j) = unshadowed_transfer(deformed_normals(p, x)).cast<double>();
  }
  const Eigen::VectorXd mean = A.rowwise().mean();
  A.colwise() -= mean;
  const core::DenseSvd svd = core::dense_svd(A);
  const Eigen::VectorXd& sigma = svd.sigma;
  int r_a = 1;
  while (r_a < sigma.size() && sigma[r_a] >= o.eps_a * sigma[0]) ++r_a;
  a.mean_transfer = mean.cast<float>();
  a.U_a = svd.U.leftCols(r_a).cast<float>();
  a.singular_values = sigma.cast<float>();
  a.rel_error.resize(sigma.size());
  const double total = sigma.squaredNorm();
  for (Eigen::Index i = 0; i < sigma.size(); ++i) {
    a.rel_error[i] =
        static_cast<float>(std::sqrt(std::max(0.0, sigma.tail(sigma.size() - i - 1).squaredNorm() / total)));
  }
  const Eigen::MatrixXd Qa = sigma.head(r_a).asDiagonal() * svd.V.leftCols(r_a).transpose();  // r_a x N_a

  // Regularized normalized RBF over q_u (§4.3): Gaussian kernels with widths
  // from the distance to the nearest other centre.
  a.nrbf_centers.resize(Na, p.rank_u());
  for (int j = 0; j < Na; ++j) a.nrbf_centers.row(j) = pp.q_u.row(a.cluster_nodes[static_cast<size_t>(j)]);
  a.nrbf_widths.resize(Na);
  for (int j = 0; j < Na; ++j) {
    float nearest = INFINITY;
    for (int k = 0; k < Na; ++k) {
      if (k != j) nearest = std::min(nearest, (a.nrbf_centers.row(j) - a.nrbf_centers.row(k)).norm());
    }
    a.nrbf_widths[j] = std::isfinite(nearest) && nearest > 0 ? nearest : 1.0f;
  }
  a.nrbf_regularization = 1e-3f;
  auto basis = [&](const Eigen::RowVectorXf& q) {
    Eigen::RowVectorXd phi(Na);
    for (int j = 0; j < Na; ++j) {
      const double d2 = (q - a.nrbf_centers.row(j)).squaredNorm();
      phi[j] = std::exp(-d2 / (2.0 * a.nrbf_widths[j] * a.nrbf_widths[j]));
    }
    return Eigen::RowVectorXd(phi / std::max(phi.sum(), 1e-300));
  };
  Eigen::MatrixXd Phi(Na, Na);
  for (int j = 0; j < Na; ++j) Phi.row(j) = basis(a.nrbf_centers.row(j));
  const Eigen::MatrixXd lhs =
      Phi.transpose() * Phi + a.nrbf_regularization * Eigen::MatrixXd::Identity(Na, Na);
  const Eigen::MatrixXd W = lhs.ldlt().solve(Phi.transpose() * Qa.transpose());  // N_a x r_a
  a.nrbf_weights = W.cast<float>();
  p.portrait.q_a.resize(N, r_a);
  for (int k = 0; k < N; ++k) p.portrait.q_a.row(k) = (basis(pp.q_u.row(k)) * W).cast<float>();
  p.appearance = std::move(a);
}

}  // namespace

core::ScenePackage make_plate_package(const PlateOptions& o) {
  ScenePackage p;
  p.attributes.scene = "plate";
  p.attributes.dt = o.dt;
  p.attributes.blend_lambda = 8.0;
  p.attributes.eps_u = 0.0;
  p.attributes.eps_a = o.appearance ? o.eps_a : 0.0;
  p.attributes.camera = std::array<float, 10>{0.5f, 0.5f, 2.6f, 0.5f, 0.5f, 0.0f, 0.0f, 1.0f, 0.0f, 40.0f};
  build_mesh(p, o.grid);
  build_palette(p);
  build_irfs(p, o);
  principal_axes(p, plate_modes(p, o.rank_u));
  velocities_and_cache(p);
  if (o.appearance) {
    fit_appearance_model(p, o);
  } else {
    p.portrait.q_a.resize(p.portrait.nodes(), 0);
  }
  core::validate_package(p, "synthetic plate");
  return p;
}

std::string package_rejection(const std::filesystem::path& path) {
  try {
    core::read_package(path);
  } catch (const core::PackageError& e) {
    return e.what();
  }
  return "";
}

}  // namespace phasecast::testing
