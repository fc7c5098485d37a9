#include "phasecast/precompute/simulation/elastic_forces.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace phasecast::precompute {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

Vector3d point(const Eigen::VectorXd& x, int i) {
  return x.segment<3>(3 * i);
}

// One element's share of the evaluation, written into slots of its own so that
// elements can be evaluated in parallel and gathered in a fixed order: the same
// sums, bit for bit, with any number of threads.
struct ElementOut {
  double energy = 0;
  Vector3d* force = nullptr;                    // one per element vertex, in the element's order
  Eigen::Triplet<double>* stiffness = nullptr;  // the next free slot; null without stiffness
};

// Adds f to the element's `local`-th vertex.
void add_force(ElementOut& out, int local, const Vector3d& f) {
  out.force[local] += f;
}

void add_block(ElementOut& out, int a, int b, const Matrix3d& block) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) *out.stiffness++ = Eigen::Triplet<double>(3 * a + r, 3 * b + c, block(r, c));
  }
}

// A degenerate element still emits its (zero) blocks: the implicit solver
// relies on a constant sparsity pattern from step to step.
template <size_t N>
void add_zero_blocks(ElementOut& out, const std::array<int, N>& v, bool with_stiffness) {
  if (!with_stiffness) return;
  for (int a : v)
    for (int b : v) add_block(out, a, b, Matrix3d::Zero());
}

// Rotation part of the polar decomposition F = R S (3 x D, D = 2 or 3).
// For tets a reflection is removed by flipping the weakest singular direction,
// which makes inverted elements push back towards their rest orientation.
template <int D>
Eigen::Matrix<double, 3, D> polar_rotation(const Eigen::Matrix<double, 3, D>& F) {
  Eigen::JacobiSVD<Eigen::Matrix<double, 3, D>> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Matrix3d U = svd.matrixU();
  Eigen::Matrix<double, D, D> V = svd.matrixV();
  if constexpr (D == 3) {
    if ((U * V.transpose()).determinant() < 0) U.col(2) = -U.col(2);
  }
  return U.template leftCols<D>() * V.transpose();
}

// Co-rotational linear element: Psi = mu |F - R|^2 + lambda/2 (tr(R^T F) - D)^2, F = X G with X the
// 3 x (D+1) corner positions and G the shape-function gradients. The stiffness is the warped linear one
// (Mueller et al. 2002): the Hessian of mu |sym(R^T F) - I|^2 + lambda/2 tr(R^T F - I)^2 at fixed R. It
// does not resist infinitesimal rotations, so Newton converges on bending-dominated motion.
template <int D>
void corotational(const std::array<int, D + 1>& v, const Eigen::Matrix<double, D, D>& Dm_inv, double measure,
                  const Lame& lame, const Eigen::VectorXd& x, bool with_stiffness, ElementOut& out) {
  Eigen::Matrix<double, D + 1, D> G;
  G.template bottomRows<D>() = Dm_inv;
  G.row(0) = -Dm_inv.colwise().sum();
  Eigen::Matrix<double, 3, D + 1> X;
  for (int a = 0; a <= D; ++a) X.col(a) = point(x, v[static_cast<size_t>(a)]);
  const Eigen::Matrix<double, 3, D> F = X * G;
  const Eigen::Matrix<double, 3, D> R = polar_rotation<D>(F);
  const double volumetric = (R.transpose() * F).trace() - D;
  out.energy += measure * (lame.mu * (F - R).squaredNorm() + 0.5 * lame.lambda * volumetric * volumetric);
  const Eigen::Matrix<double, 3, D> P = 2 * lame.mu * (F - R) + lame.lambda * volumetric * R;
  const Eigen::Matrix<double, 3, D + 1> forces = -measure * P * G.transpose();
  for (int a = 0; a <= D; ++a) add_force(out, a, forces.col(a));
  if (!with_stiffness) return;
  const Eigen::Matrix<double, D + 1, D + 1> GG = G * G.transpose();
  const Eigen::Matrix<double, 3, D + 1> W = R * G.transpose();
  const Matrix3d RRt = R * R.transpose();
  for (int a = 0; a <= D; ++a) {
    for (int b = 0; b <= D; ++b) {
      const Matrix3d block = measure * (lame.mu * GG(a, b) * RRt + lame.mu * W.col(b) * W.col(a).transpose() +
                                        lame.lambda * W.col(a) * W.col(b).transpose());
      add_block(out, v[static_cast<size_t>(a)], v[static_cast<size_t>(b)], block);
    }
  }
}

// Cross-product matrix: skew(a) b = a x b.
Matrix3d skew(const Vector3d& a) {
  Matrix3d m;
  m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return m;
}

// A positive semi-definite stand-in for an indefinite Hessian: negative
// eigenvalues replaced by their magnitudes (Chen et al. 2024, "Trust-region
// eigenvalue filtering for projected Newton"). Clamping them to zero instead
// leaves compressed rubber without curvature in its flip modes, and the paper
// toy's two Newton iterations overshot there until it blew up. A Cholesky
// factorization spots the already definite case for a fraction of the cost.
template <int N>
Eigen::Matrix<double, N, N> psd_projection(const Eigen::Matrix<double, N, N>& H) {
  if (Eigen::LLT<Eigen::Matrix<double, N, N>>(H).info() == Eigen::Success) return H;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(H);
  return eig.eigenvectors() * eig.eigenvalues().cwiseAbs().asDiagonal() * eig.eigenvectors().transpose();
}

// Stable neo-Hookean tetrahedron (Smith, de Goes & Kim 2018, without their log term):
//   Psi = mu/2 (I_C - 3) - mu (J - 1) + lambda/2 (J - 1)^2,  I_C = |F|^2, J = det F,
// their mu/2 (I_C - 3) + lambda/2 (J - alpha)^2 with alpha = 1 + mu/lambda less its constant, so Psi(I) = 0.
// It linearises to mu |eps|^2 + (lambda - mu)/2 tr(eps)^2, so lambda = Lame lambda + mu matches linear
// elasticity at small strain. Defined for J <= 0, it pushes inverted tets back. The stiffness is the
// exact Hessian, mu I + lambda g g^T + (lambda (J - 1) - mu) d2J/dF2 on vec(F) with g = vec(dJ/dF),
// made positive semi-definite by psd_projection.
void stable_neo_hookean(const TetElement& t, const Eigen::VectorXd& x, bool with_stiffness, ElementOut& out) {
  Eigen::Matrix<double, 4, 3> G;
  G.bottomRows<3>() = t.Dm_inv;
  G.row(0) = -t.Dm_inv.colwise().sum();
  Eigen::Matrix<double, 3, 4> X;
  for (int a = 0; a < 4; ++a) X.col(a) = point(x, t.v[static_cast<size_t>(a)]);
  const Matrix3d F = X * G;
  const double mu = t.lame.mu, lambda = t.lame.lambda + t.lame.mu;
  const double J = F.determinant();
  Matrix3d dJdF;  // the cofactor matrix
  dJdF << F.col(1).cross(F.col(2)), F.col(2).cross(F.col(0)), F.col(0).cross(F.col(1));
  out.energy +=
      t.volume * (0.5 * mu * (F.squaredNorm() - 3) - mu * (J - 1) + 0.5 * lambda * (J - 1) * (J - 1));
  const double s = lambda * (J - 1) - mu;
  const Matrix3d P = mu * F + s * dJdF;
  const Eigen::Matrix<double, 3, 4> forces = -t.volume * P * G.transpose();
  for (int a = 0; a < 4; ++a) add_force(out, a, forces.col(a));
  if (!with_stiffness) return;
  using Matrix9d = Eigen::Matrix<double, 9, 9>;
  const Eigen::Map<const Eigen::Matrix<double, 9, 1>> g(dJdF.data());
  Matrix9d H = mu * Matrix9d::Identity() + lambda * g * g.transpose();
  // d2J/dF2: column i of cof F is f_j x f_k, (i, j, k) cyclic.
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3, k = (i + 2) % 3;
    H.block<3, 3>(3 * i, 3 * j) -= s * skew(F.col(k));
    H.block<3, 3>(3 * i, 3 * k) += s * skew(F.col(j));
  }
  H = psd_projection<9>(H);
  Eigen::Matrix<double, 9, 12> B = Eigen::Matrix<double, 9, 12>::Zero();  // vec(F) = B vec(X)
  for (int a = 0; a < 4; ++a)
    for (int i = 0; i < 3; ++i) B.block<3, 3>(3 * i, 3 * a) = G(a, i) * Matrix3d::Identity();
  const Eigen::Matrix<double, 12, 12> K = t.volume * B.transpose() * H * B;
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b)
      add_block(out, t.v[static_cast<size_t>(a)], t.v[static_cast<size_t>(b)], K.block<3, 3>(3 * a, 3 * b));
  }
}

// Gradient of the dihedral angle (Bridson et al. 2003, bending modes u1..u4).
std::array<Vector3d, 4> dihedral_gradient(const std::array<Vector3d, 4>& p) {
  const Vector3d e = p[1] - p[0];
  const double len = e.norm();
  const Vector3d e_hat = e / len;
  const Vector3d nA = e.cross(p[2] - p[0]);
  const Vector3d nB = (p[3] - p[0]).cross(e);
  const Vector3d a = nA / nA.squaredNorm();
  const Vector3d b = nB / nB.squaredNorm();
  return {-((p[2] - p[1]).dot(e_hat) * a + (p[3] - p[1]).dot(e_hat) * b),
          (p[2] - p[0]).dot(e_hat) * a + (p[3] - p[0]).dot(e_hat) * b, -len * a, -len * b};
}

void hinge(const HingeElement& h, const Eigen::VectorXd& x, bool with_stiffness, ElementOut& out) {
  std::array<Vector3d, 4> p;
  for (int k = 0; k < 4; ++k) p[static_cast<size_t>(k)] = point(x, h.v[static_cast<size_t>(k)]);
  const Vector3d nA = (p[1] - p[0]).cross(p[2] - p[0]);
  const Vector3d nB = (p[3] - p[0]).cross(p[1] - p[0]);
  if (nA.squaredNorm() < 1e-24 || nB.squaredNorm() < 1e-24) {  // collapsed: no defined angle
    add_zero_blocks(out, h.v, with_stiffness);
    return;
  }
  const double delta = dihedral_angle(p[0], p[1], p[2], p[3]) - h.rest_angle;
  const double wrapped = std::remainder(delta, 2 * M_PI);
  out.energy += 0.5 * h.stiffness * wrapped * wrapped;
  const auto grad = dihedral_gradient(p);
  for (int k = 0; k < 4; ++k) add_force(out, k, -h.stiffness * wrapped * grad[static_cast<size_t>(k)]);
  if (!with_stiffness) return;
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      add_block(out, h.v[static_cast<size_t>(a)], h.v[static_cast<size_t>(b)],
                h.stiffness * grad[static_cast<size_t>(a)] * grad[static_cast<size_t>(b)].transpose());
    }
  }
}

void rod_stretch(const RodStretchElement& r, const Eigen::VectorXd& x, bool with_stiffness, ElementOut& out) {
  const Vector3d d = point(x, r.b) - point(x, r.a);
  const double l = d.norm();
  if (l < 1e-12) {
    add_zero_blocks(out, std::array<int, 2>{r.a, r.b}, with_stiffness);
    return;
  }
  const Vector3d dir = d / l;
  out.energy += 0.5 * r.stiffness * (l - r.rest_length) * (l - r.rest_length);
  const Vector3d f = r.stiffness * (l - r.rest_length) * dir;
  add_force(out, 0, f);
  add_force(out, 1, -f);
  if (!with_stiffness) return;
  // Transverse term only when stretched, which keeps the block positive semi-definite.
  const double transverse = std::max(0.0, 1.0 - r.rest_length / l);
  const Matrix3d K =
      r.stiffness * (dir * dir.transpose() + transverse * (Matrix3d::Identity() - dir * dir.transpose()));
  add_block(out, r.a, r.a, K);
  add_block(out, r.b, r.b, K);
  add_block(out, r.a, r.b, -K);
  add_block(out, r.b, r.a, -K);
}

void rod_bend(const RodBendElement& r, const Eigen::VectorXd& x, bool with_stiffness, ElementOut& out) {
  const Vector3d e1 = point(x, r.b) - point(x, r.a);
  const Vector3d e2 = point(x, r.c) - point(x, r.b);
  const double l1 = e1.norm(), l2 = e2.norm();
  if (l1 < 1e-12 || l2 < 1e-12) {
    add_zero_blocks(out, std::array<int, 3>{r.a, r.b, r.c}, with_stiffness);
    return;
  }
  const Vector3d t1 = e1 / l1, t2 = e2 / l2;
  const Vector3d d = t2 - t1;  // discrete curvature vector, |d| = 2 sin(theta / 2)
  const Matrix3d P1 = (Matrix3d::Identity() - t1 * t1.transpose()) / l1;
  const Matrix3d P2 = (Matrix3d::Identity() - t2 * t2.transpose()) / l2;
  const std::array<Matrix3d, 3> J = {P1, Matrix3d(-P1 - P2), P2};  // dd/dx_a, dd/dx_b, dd/dx_c
  const std::array<int, 3> idx = {r.a, r.b, r.c};
  // E = 1/2 k (|d| - c0)^2; with a straight rest shape (c0 = 0) this is 1/2 k |d|^2, smooth at d = 0.
  Vector3d residual = d;
  Matrix3d weight = Matrix3d::Identity();
  if (r.rest_turning > 1e-9) {
    const double dn = d.norm();
    if (dn < 1e-12) {
      add_zero_blocks(out, idx, with_stiffness);
      return;
    }
    residual = (dn - r.rest_turning) * d / dn;
    weight = d * d.transpose() / (dn * dn);
  }
  out.energy += 0.5 * r.stiffness * residual.squaredNorm();
  for (int k = 0; k < 3; ++k)
    add_force(out, k, -r.stiffness * J[static_cast<size_t>(k)].transpose() * residual);
  if (!with_stiffness) return;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      add_block(out, idx[static_cast<size_t>(a)], idx[static_cast<size_t>(b)],
                r.stiffness * J[static_cast<size_t>(a)].transpose() * weight * J[static_cast<size_t>(b)]);
    }
  }
}

// Evaluates each kind of element in parallel (TBB), every element into its own
// slots, then gathers forces and energy serially in element order.
class ElementEvaluator {
 public:
  ElementEvaluator(const Eigen::VectorXd& x, bool with_stiffness) : x_(x), with_stiffness_(with_stiffness) {}

  // `corners(e)` lists element e's vertices; `eval` evaluates it into its slots.
  template <class Element, class Corners, class Eval>
  void add(const std::vector<Element>& elements, int n, Corners corners, Eval eval) {
    if (elements.empty()) return;
    const size_t first_force = forces_.size(), first_triplet = triplets_.size();
    const auto count = elements.size(), per_force = static_cast<size_t>(n),
               per_block = with_stiffness_ ? 9 * per_force * per_force : 0;
    forces_.resize(first_force + count * per_force, Vector3d::Zero());
    triplets_.resize(first_triplet + count * per_block);
    energies_.resize(energies_.size() + count);
    const size_t first_energy = energies_.size() - count;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 64), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        ElementOut out;
        out.force = forces_.data() + first_force + i * per_force;
        out.stiffness = with_stiffness_ ? triplets_.data() + first_triplet + i * per_block : nullptr;
        eval(elements[i], x_, with_stiffness_, out);
        energies_[first_energy + i] = out.energy;
      }
    });
    for (const auto& element : elements) {
      for (int v : corners(element)) corner_vertices_.push_back(v);
    }
  }

  ElasticEvaluation gather() {
    ElasticEvaluation out;
    out.force = Eigen::VectorXd::Zero(x_.size());
    for (size_t k = 0; k < forces_.size(); ++k) out.force.segment<3>(3 * corner_vertices_[k]) += forces_[k];
    for (double e : energies_) out.energy += e;
    out.stiffness = std::move(triplets_);
    return out;
  }

 private:
  const Eigen::VectorXd& x_;
  bool with_stiffness_;
  std::vector<Vector3d> forces_;
  std::vector<int> corner_vertices_;
  std::vector<double> energies_;
  std::vector<Eigen::Triplet<double>> triplets_;
};

}  // namespace

double dihedral_angle(const Vector3d& x0, const Vector3d& x1, const Vector3d& x2, const Vector3d& x3) {
  const Vector3d e = x1 - x0;
  const Vector3d nA = e.cross(x2 - x0);
  const Vector3d nB = (x3 - x0).cross(e);
  return std::atan2(nA.cross(nB).dot(e.normalized()), nA.dot(nB));
}

ElasticEvaluation evaluate_elastic(const DeformableModel& model, const Eigen::VectorXd& x,
                                   bool with_stiffness) {
  ElementEvaluator e(x, with_stiffness);
  e.add(
      model.membranes, 3, [](const MembraneElement& m) { return m.v; },
      [](const MembraneElement& m, const Eigen::VectorXd& xs, bool k, ElementOut& out) {
        corotational<2>(m.v, m.Dm_inv, m.area, m.lame, xs, k, out);
      });
  e.add(
      model.hinges, 4, [](const HingeElement& h) { return h.v; }, hinge);
  const auto ends = [](const RodStretchElement& r) { return std::array<int, 2>{r.a, r.b}; };
  e.add(model.rod_stretch, 2, ends, rod_stretch);
  e.add(model.braces, 2, ends, rod_stretch);  // a brace's energy is a rod edge's
  e.add(
      model.rod_bend, 3,
      [](const RodBendElement& r) {
        return std::array<int, 3>{r.a, r.b, r.c};
      },
      rod_bend);
  e.add(
      model.tets, 4, [](const TetElement& t) { return t.v; },
      [](const TetElement& t, const Eigen::VectorXd& xs, bool k, ElementOut& out) {
        if (t.energy == TetEnergy::stable_neo_hookean) return stable_neo_hookean(t, xs, k, out);
        corotational<3>(t.v, t.Dm_inv, t.volume, t.lame, xs, k, out);
      });
  return e.gather();
}

}  // namespace phasecast::precompute
