#include "phasecast/precompute/simulation/continuous_collision.h"
#include "phasecast/precompute/simulation/elastic_forces.h"
#include "phasecast/precompute/simulation/self_collision.h"
#include "phasecast/precompute/simulation/simulator.h"

#include <fmt/format.h>

#include <Eigen/CholmodSupport>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <utility>
#include <vector>

namespace phasecast::precompute {
namespace {

using Eigen::Vector3d;
using Eigen::VectorXd;

// Relative normal speed, times the step, that a collision impulse leaves between
// a pair, as a fraction of the thickness: enough to part it, too little to bounce.
constexpr double kSeparation = 0.1;
constexpr int kCcdPasses = 6;  // impulse passes before the impact-zone fail-safe

Vector3d to_vector3(const VectorXd& alpha, int expected, const char* what) {
  if (alpha.size() != expected) {
    throw SimulationError(
        fmt::format("{}: expected a palette parameter of size {}, got {}", what, expected, alpha.size()));
  }
  if (!alpha.allFinite())
    throw SimulationError(fmt::format("{}: palette parameter has a NaN or Inf entry", what));
  return alpha.head<3>();
}

// Debian's CHOLMOD opens OpenMP regions of a fixed 4 threads inside every large
// supernode. Beside our own threads on a 2-core machine they spent half of a
// paper-size cloth frame waking and parking threads (perf: libgomp and futex
// 49 %), so the factorization runs serial: the OpenMP limit of active levels is
// 0 in the calling thread (a per-thread setting). Looked up at run time because
// libgomp is there only when CHOLMOD brought it; the numbers do not depend on it.
void serial_openmp_in_this_thread() {
  using SetLevels = void (*)(int);
  static const auto set_levels =
      reinterpret_cast<SetLevels>(::dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"));
  if (set_levels) set_levels(0);
}

// CHOLMOD's supernodal factorization and solve call BLAS, and Debian's serial
// OpenBLAS is not safe to call from two threads at once (it is built without
// USE_LOCKING): two sampled chains factorizing together got garbage ("not
// positive definite" at the first step). Concurrent chains take turns here.
std::mutex& blas_turn() {
  static std::mutex m;
  return m;
}

// The implicit step's sparse Cholesky (settings.linear_solver), its symbolic
// analysis done once: the system's pattern never changes.
class StepFactorization {
 public:
  using Matrix = Eigen::SparseMatrix<double>;
  explicit StepFactorization(LinearSolver kind) : kind_(kind) {}

  void analyze(const Matrix& A) {
    if (kind_ == LinearSolver::supernodal) {
      serial_openmp_in_this_thread();
      supernodal_.analyzePattern(A);
    } else {
      simplicial_.analyzePattern(A);
    }
  }
  bool factorize(const Matrix& A) {
    if (kind_ == LinearSolver::supernodal) {
      const std::lock_guard turn(blas_turn());
      serial_openmp_in_this_thread();
      supernodal_.factorize(A);
      return supernodal_.info() == Eigen::Success;
    }
    simplicial_.factorize(A);
    return simplicial_.info() == Eigen::Success;
  }
  VectorXd solve(const VectorXd& b) {
    if (kind_ == LinearSolver::supernodal) {
      const std::lock_guard turn(blas_turn());
      return supernodal_.solve(b);
    }
    return simplicial_.solve(b);
  }

 private:
  LinearSolver kind_;
  Eigen::SimplicialLDLT<Matrix> simplicial_;
  Eigen::CholmodSupernodalLLT<Matrix> supernodal_;
};

class ImplicitSimulator final : public Simulator {
 public:
  ImplicitSimulator(DeformableModel model, const SimulationSettings& settings, const SupportSettings& support)
      : model_(std::move(model)),
        settings_(settings),
        support_(support),
        factorization_(settings.linear_solver),
        self_collision_(model_.self_collision ? model_.surface : Eigen::MatrixXi(0, 3), model_.thickness,
                        model_.self_friction),
        continuous_collision_(model_.self_collision ? model_.surface : Eigen::MatrixXi(0, 3),
                              kSeparation * model_.thickness, kCcdPasses, model_.incremental_ccd) {
    if (!(settings_.frame_dt > 0) || settings_.substeps < 1 || settings_.newton_iterations < 1) {
      throw SimulationError(
          fmt::format("simulation settings: expected frame_dt > 0, substeps >= 1, "
                      "newton_iterations >= 1, got {}, {}, {}",
                      settings_.frame_dt, settings_.substeps, settings_.newton_iterations));
    }
    const double gamma = settings_.newmark_gamma, beta = settings_.newmark_beta;
    if (settings_.integrator == Integrator::newmark &&
        !(gamma >= 0.5 && beta >= (gamma + 0.5) * (gamma + 0.5) / 4)) {
      throw SimulationError(
          fmt::format("simulation settings: expected newmark_gamma >= 1/2 and newmark_beta >= "
                      "(newmark_gamma + 1/2)^2 / 4 (unconditionally stable Newmark), got {}, {}",
                      gamma, beta));
    }
    free_index_.assign(static_cast<size_t>(3 * model_.vertices()), -1);
    for (int i = 0; i < model_.vertices(); ++i) {
      if (model_.pinned[static_cast<size_t>(i)]) continue;
      for (int k = 0; k < 3; ++k) free_index_[static_cast<size_t>(3 * i + k)] = free_count_++;
    }
    inverse_mass_ = VectorXd::Zero(model_.vertices());
    for (int i = 0; i < model_.vertices(); ++i) {
      if (!model_.pinned[static_cast<size_t>(i)]) inverse_mass_[i] = 1.0 / model_.mass[i];
    }
    state_ = rest_state();
  }

  int vertices() const override { return model_.vertices(); }
  double frame_dt() const override { return settings_.frame_dt; }
  int alpha_size() const override { return 3; }

  SimState rest_state() const override {
    SimState s;
    s.x = model_.rest;
    s.v = VectorXd::Zero(model_.rest.size());
    return s;
  }

  void reset(const SimState& state) override {
    if (state.x.size() != model_.rest.size() || state.v.size() != model_.rest.size()) {
      throw SimulationError(fmt::format("reset: expected a state of {} coordinates, got x {} and v {}",
                                        model_.rest.size(), state.x.size(), state.v.size()));
    }
    if (!state.x.allFinite() || !state.v.allFinite())
      throw SimulationError("reset: state has a NaN or Inf entry");
    state_ = state;
  }

  const SimState& state() const override { return state_; }

  void impulse(const VectorXd& alpha_impulse) override {
    apply_support_jump(support_.impulse(state_.support, checked_alpha(alpha_impulse, "impulse")));
  }

  void step(const VectorXd& alpha_forcing) override {
    apply_support_jump(support_.hold(state_.support, checked_alpha(alpha_forcing, "step")));
    const double h = settings_.frame_dt / settings_.substeps;
    for (int s = 0; s < settings_.substeps; ++s) substep(h);
    state_.time += settings_.frame_dt;
  }

  Eigen::Matrix<double, 3, 4> support_transform() const override {
    return support_.transform(state_.support);
  }

 private:
  // A support velocity that moves scene points faster than max_speed would
  // make fictitious forces of arbitrary size: rejected rather than integrated.
  Vector3d checked_alpha(const VectorXd& alpha, const char* what) const {
    const Vector3d w = to_vector3(alpha, 3, what);
    double fastest = 0;
    for (int i = 0; i < vertices(); ++i) {
      fastest = std::max(fastest, support_.point_velocity(w, state_.x.segment<3>(3 * i)).norm());
    }
    if (fastest > settings_.max_speed) {
      throw SimulationError(
          fmt::format("{}: support velocity ({}, {}, {}) moves scene points at {:.4g} m/s, above "
                      "max_speed {} m/s",
                      what, w.x(), w.y(), w.z(), fastest, settings_.max_speed));
    }
    return w;
  }

  bool is_free(int vertex) const { return !model_.pinned[static_cast<size_t>(vertex)]; }

  // A jump dw of the support velocity changes every free particle's velocity
  // relative to the frame by -dw x r (or -dw): the impulsive fictitious force.
  void apply_support_jump(const Vector3d& dw) {
    if (dw.isZero(0)) return;
    for (int i = 0; i < vertices(); ++i) {
      if (!is_free(i)) continue;
      state_.v.segment<3>(3 * i) -= support_.point_velocity(dw, state_.x.segment<3>(3 * i));
    }
    clamp_speeds();
  }

  // External forces: gravity, fictitious forces of the moving frame, air drag.
  // Returns the drag's velocity Jacobian blocks (per vertex, positive semi-definite) in `drag_blocks`.
  VectorXd external_forces(const VectorXd& x, const VectorXd& v, const FrameKinematics& k,
                           std::vector<Eigen::Matrix3d>& drag_blocks) const {
    VectorXd f = VectorXd::Zero(x.size());
    const Vector3d& w = k.angular_velocity;
    for (int i = 0; i < vertices(); ++i) {
      const double m = model_.mass[i];
      const Vector3d r = x.segment<3>(3 * i) - support_.settings().pivot;
      const Vector3d vi = v.segment<3>(3 * i);
      f.segment<3>(3 * i) = m * (settings_.gravity - k.linear_acceleration - k.angular_acceleration.cross(r) -
                                 w.cross(w.cross(r)) - 2 * w.cross(vi));
    }
    drag_blocks.assign(static_cast<size_t>(vertices()), Eigen::Matrix3d::Zero());
    for (const auto& d : model_.drag) {
      const Vector3d a = x.segment<3>(3 * d.v[0]), b = x.segment<3>(3 * d.v[1]), c = x.segment<3>(3 * d.v[2]);
      const Vector3d n2 = (b - a).cross(c - a);
      const double twice_area = n2.norm();
      if (twice_area < 1e-14) continue;
      const Vector3d n = n2 / twice_area;
      const double share = d.coefficient * 0.5 * twice_area / 3.0;
      for (int vtx : d.v) {
        const Vector3d r = x.segment<3>(3 * vtx) - support_.settings().pivot;
        const Vector3d air_relative = v.segment<3>(3 * vtx) + k.linear_velocity + w.cross(r);
        f.segment<3>(3 * vtx) -= share * n.dot(air_relative) * n;
        drag_blocks[static_cast<size_t>(vtx)] += share * n * n.transpose();
      }
    }
    return f;
  }

  // How the step weighs damping and stiffness in its system matrix: h and h^2
  // for backward Euler, gamma h and beta h^2 for Newmark.
  struct StepWeights {
    double damping;
    double stiffness;
  };

  // Newmark's start of step: f0 = f(x0, v0) = M a0, and the step velocity u = (x - x0) / h at v = v0.
  struct NewmarkStart {
    VectorXd force;
    VectorXd drift;
  };

  NewmarkStart newmark_start(const VectorXd& x0, const VectorXd& v0, const FrameKinematics& kin,
                             double h) const {
    // Recomputed from the state rather than carried over: contact, clamps and
    // support jumps change the state between steps, and a run restarted from
    // any recorded (x, v) continues exactly.
    const bool damped = settings_.stiffness_damping > 0;
    std::vector<Eigen::Matrix3d> drag_blocks;
    NewmarkStart start;
    start.force = forces(evaluate_elastic(model_, x0, damped), x0, v0, kin, drag_blocks);
    const double gamma = settings_.newmark_gamma, beta = settings_.newmark_beta;
    start.drift = v0 + (h * (0.5 - beta / gamma)) * inverse_mass_times(start.force);
    return start;
  }

  // Every force at positions x and velocities v: elastic, external, Rayleigh damping.
  VectorXd forces(const ElasticEvaluation& el, const VectorXd& x, const VectorXd& v,
                  const FrameKinematics& kin, std::vector<Eigen::Matrix3d>& drag_blocks) const {
    const double a = settings_.mass_damping, b = settings_.stiffness_damping;
    VectorXd Kv = VectorXd::Zero(x.size());
    for (const auto& t : el.stiffness) Kv[t.row()] += t.value() * v[t.col()];
    return el.force + external_forces(x, v, kin, drag_blocks) - a * mass_times(v) - b * Kv;
  }

  // One implicit step of length h, solved by Newton for the end-of-step velocities v:
  //   backward Euler  M (v - v0) = h f(x0 + h v, v);
  //   Newmark         M (v - v0) = h ((1 - gamma) f0 + gamma f(x0 + h u, v)), f0 = f(x0, v0) = M a0,
  //                   u = v0 + (beta/gamma) (v - v0) + h (1/2 - beta/gamma) a0,
  // which is Newmark's x = x0 + h v0 + h^2 ((1/2 - beta) a0 + beta a) with a from v = v0 + h ((1 - gamma)
  // a0 + gamma a). Contact then acts on the step velocity u = (x - x0) / h (v itself for backward Euler).
  void substep(double h) {
    const FrameKinematics kin = support_.kinematics(state_.support);
    const VectorXd x0 = state_.x, v0 = state_.v;
    const bool newmark = settings_.integrator == Integrator::newmark;
    const double gamma = settings_.newmark_gamma, beta = settings_.newmark_beta;
    const NewmarkStart start = newmark ? newmark_start(x0, v0, kin, h) : NewmarkStart{};
    const StepWeights weights = newmark ? StepWeights{gamma * h, beta * h * h} : StepWeights{h, h * h};
    const auto step_velocity = [&](const VectorXd& v) -> VectorXd {
      return newmark ? VectorXd(start.drift + (beta / gamma) * (v - v0)) : v;
    };
    VectorXd v = v0;
    std::vector<Eigen::Matrix3d> drag_blocks;
    for (int it = 0; it < settings_.newton_iterations; ++it) {
      const VectorXd x = x0 + h * step_velocity(v);
      const ElasticEvaluation el = evaluate_elastic(model_, x, true);
      const VectorXd f = forces(el, x, v, kin, drag_blocks);
      const VectorXd residual =
          newmark ? VectorXd(mass_times(v - v0) - h * ((1 - gamma) * start.force + gamma * f))
                  : VectorXd(mass_times(v - v0) - h * f);
      const VectorXd delta = solve(el.stiffness, drag_blocks, residual, weights);
      v += delta;
      if (delta.lpNorm<Eigen::Infinity>() < settings_.newton_tolerance) break;
    }
    VectorXd u = step_velocity(v);
    const VectorXd unfiltered = u;
    self_collision_.filter(x0, u, h, inverse_mass_);
    clip_obstacles(x0, u, h);
    if (model_.self_collision) {
      continuous_collision_.resolve(x0, u, h, inverse_mass_,
                                    [this](int, const Vector3d& end) { return clear_of_obstacles(end); });
    }
    // Contact changes Newmark's end velocity by what it changed the step's: an
    // inelastic impulse, as for backward Euler, whose end velocity is u.
    state_.v = newmark ? VectorXd(v + (u - unfiltered)) : u;
    state_.x = x0 + h * u;
    if (!model_.self_collision) resolve_obstacles();  // with CCD every end is already clear
    clamp_speeds();
    apply_support_jump(support_.advance(state_.support, h));
  }

  VectorXd mass_times(const VectorXd& v) const {
    VectorXd out(v.size());
    for (int i = 0; i < vertices(); ++i) out.segment<3>(3 * i) = model_.mass[i] * v.segment<3>(3 * i);
    return out;
  }

  // M^-1 f on the free particles, zero on pinned ones.
  VectorXd inverse_mass_times(const VectorXd& f) const {
    VectorXd out(f.size());
    for (int i = 0; i < vertices(); ++i) out.segment<3>(3 * i) = inverse_mass_[i] * f.segment<3>(3 * i);
    return out;
  }

  // Solves A delta = -residual on the free coordinates, A = M (1 + c a) + (c b + s) K + c D_drag with
  // (c, s) the step's weights: (h, h^2) for backward Euler, (gamma h, beta h^2) for Newmark.
  VectorXd solve(const std::vector<Eigen::Triplet<double>>& stiffness,
                 const std::vector<Eigen::Matrix3d>& drag_blocks, const VectorXd& residual, StepWeights w) {
    const double a = settings_.mass_damping, b = settings_.stiffness_damping;
    const double k_scale = w.damping * b + w.stiffness;
    triplets_.clear();
    triplets_.reserve(stiffness.size() + static_cast<size_t>(3 * free_count_));
    for (const auto& t : stiffness) {
      const int r = free_index_[static_cast<size_t>(t.row())], c = free_index_[static_cast<size_t>(t.col())];
      if (r >= 0 && c >= 0) triplets_.emplace_back(r, c, k_scale * t.value());
    }
    VectorXd rhs(free_count_);
    for (int i = 0; i < vertices(); ++i) {
      if (!is_free(i)) continue;
      for (int r = 0; r < 3; ++r) {
        const int fr = free_index_[static_cast<size_t>(3 * i + r)];
        rhs[fr] = -residual[3 * i + r];
        for (int c = 0; c < 3; ++c) {
          const double m = r == c ? model_.mass[i] * (1 + w.damping * a) : 0.0;
          triplets_.emplace_back(fr, free_index_[static_cast<size_t>(3 * i + c)],
                                 m + w.damping * drag_blocks[static_cast<size_t>(i)](r, c));
        }
      }
    }
    assemble(triplets_);
    if (!factorization_.factorize(A_)) {
      throw SimulationError(
          fmt::format("implicit step at t={:.4f} s: the system matrix is not positive definite "
                      "(check for negative masses or stiffnesses)",
                      state_.time));
    }
    const VectorXd solution = factorization_.solve(rhs);
    VectorXd delta = VectorXd::Zero(residual.size());
    for (size_t d = 0; d < free_index_.size(); ++d) {
      if (free_index_[d] >= 0) delta[static_cast<Eigen::Index>(d)] = solution[free_index_[d]];
    }
    return delta;
  }

  // The pattern of A never changes (every element always emits its blocks), so
  // the first assembly records where each triplet lands in A's value array and
  // later assemblies only scatter-add values (no sort), then reuse the symbolic
  // factorization.
  void assemble(const std::vector<Eigen::Triplet<double>>& triplets) {
    if (!pattern_analyzed_) {
      A_.resize(free_count_, free_count_);
      A_.setFromTriplets(triplets.begin(), triplets.end());
      A_.makeCompressed();
      slots_.resize(triplets.size());
      for (size_t k = 0; k < triplets.size(); ++k) {
        const int* begin = A_.innerIndexPtr() + A_.outerIndexPtr()[triplets[k].col()];
        const int* end = A_.innerIndexPtr() + A_.outerIndexPtr()[triplets[k].col() + 1];
        slots_[k] = static_cast<int>(std::lower_bound(begin, end, triplets[k].row()) - A_.innerIndexPtr());
      }
      factorization_.analyze(A_);
      pattern_analyzed_ = true;
      return;
    }
    if (triplets.size() != slots_.size()) {
      throw SimulationError(
          fmt::format("implicit step at t={:.4f} s: stiffness pattern changed ({} entries, expected {})",
                      state_.time, triplets.size(), slots_.size()));
    }
    double* values = A_.valuePtr();
    std::fill(values, values + A_.nonZeros(), 0.0);
    for (size_t k = 0; k < triplets.size(); ++k) values[slots_[k]] += triplets[k].value();
  }

  // Velocity-level obstacle contact, before continuous collision sees the step:
  // a free particle whose end of step falls within `thickness` of a box ends on
  // the padded face it came through instead (inward normal velocity removed),
  // its tangential velocity damped by friction.
  void clip_obstacles(const VectorXd& x0, VectorXd& v, double h) const {
    const double th = model_.thickness;
    for (const auto& box : model_.obstacles) {
      const Vector3d lo = box.min.array() - th, hi = box.max.array() + th;
      for (int i = 0; i < vertices(); ++i) {
        if (!is_free(i)) continue;
        const Vector3d p0 = x0.segment<3>(3 * i), end = p0 + h * v.segment<3>(3 * i);
        if ((end.array() <= lo.array()).any() || (end.array() >= hi.array()).any()) continue;
        const bool was_inside = (p0.array() > lo.array()).all() && (p0.array() < hi.array()).all();
        int axis = 0;
        double depth = 1e300, face = 0;
        for (int k = 0; k < 3; ++k) {
          if ((was_inside || p0[k] <= lo[k]) && end[k] - lo[k] < depth)
            depth = end[k] - lo[k], axis = k, face = lo[k];
          if ((was_inside || p0[k] >= hi[k]) && hi[k] - end[k] < depth)
            depth = hi[k] - end[k], axis = k, face = hi[k];
        }
        v[3 * i + axis] = (face - p0[axis]) / h;
        for (int k = 0; k < 3; ++k) {
          if (k != axis) v[3 * i + k] *= 1 - settings_.friction;
        }
      }
    }
  }

  // Whether an end of step keeps half the thickness clear of every box (the
  // clip leaves a full thickness; impulses may take up to half of it).
  bool clear_of_obstacles(const Vector3d& p) const {
    const double margin = 0.5 * model_.thickness;
    for (const auto& box : model_.obstacles) {
      if ((p.array() > box.min.array() - margin).all() && (p.array() < box.max.array() + margin).all())
        return false;
    }
    return true;
  }

  // Keeps free particles `thickness` outside every obstacle box; the inward
  // normal velocity is removed and the tangential velocity damped by friction.
  void resolve_obstacles() {
    const double th = model_.thickness;
    for (const auto& box : model_.obstacles) {
      const Vector3d lo = box.min.array() - th, hi = box.max.array() + th;
      for (int i = 0; i < vertices(); ++i) {
        if (!is_free(i)) continue;
        Vector3d p = state_.x.segment<3>(3 * i);
        if ((p.array() <= lo.array()).any() || (p.array() >= hi.array()).any()) continue;
        int axis = 0;
        double depth = 1e300, side = 1;
        for (int k = 0; k < 3; ++k) {
          if (p[k] - lo[k] < depth) depth = p[k] - lo[k], axis = k, side = -1;
          if (hi[k] - p[k] < depth) depth = hi[k] - p[k], axis = k, side = 1;
        }
        p[axis] = side > 0 ? hi[axis] : lo[axis];
        state_.x.segment<3>(3 * i) = p;
        Vector3d vel = state_.v.segment<3>(3 * i);
        if (vel[axis] * side < 0) vel[axis] = 0;
        for (int k = 0; k < 3; ++k) {
          if (k != axis) vel[k] *= 1 - settings_.friction;
        }
        state_.v.segment<3>(3 * i) = vel;
      }
    }
  }

  void clamp_speeds() {
    for (int i = 0; i < vertices(); ++i) {
      const double speed = state_.v.segment<3>(3 * i).norm();
      if (speed > settings_.max_speed) state_.v.segment<3>(3 * i) *= settings_.max_speed / speed;
    }
  }

  DeformableModel model_;
  SimulationSettings settings_;
  SupportMotion support_;
  StepFactorization factorization_;
  SelfCollision self_collision_;
  ContinuousCollision continuous_collision_;
  VectorXd inverse_mass_;
  SimState state_;
  std::vector<int> free_index_;
  int free_count_ = 0;
  std::vector<Eigen::Triplet<double>> triplets_;
  Eigen::SparseMatrix<double> A_;
  std::vector<int> slots_;
  bool pattern_analyzed_ = false;
};

}  // namespace

std::unique_ptr<Simulator> make_implicit_simulator(DeformableModel model, const SimulationSettings& settings,
                                                   const SupportSettings& support) {
  if (model.mass.size() * 3 != model.rest.size() ||
      model.pinned.size() != static_cast<size_t>(model.mass.size())) {
    throw SimulationError(
        fmt::format("model: expected 3V rest coordinates and V masses and pins, got {}, {}, {}",
                    model.rest.size(), model.mass.size(), model.pinned.size()));
  }
  for (Eigen::Index i = 0; i < model.mass.size(); ++i) {
    if (!(model.mass[i] > 0)) {
      throw SimulationError(
          fmt::format("model: vertex {} has mass {} (expected > 0; is it in no element?)", i, model.mass[i]));
    }
  }
  return std::make_unique<ImplicitSimulator>(std::move(model), settings, support);
}

double mechanical_energy(const DeformableModel& model, const SimulationSettings& settings,
                         const SimState& state) {
  double energy = evaluate_elastic(model, state.x, false).energy;
  for (int i = 0; i < model.vertices(); ++i) {
    energy += 0.5 * model.mass[i] * state.v.segment<3>(3 * i).squaredNorm() -
              model.mass[i] * settings.gravity.dot(state.x.segment<3>(3 * i));
  }
  return energy;
}

}  // namespace phasecast::precompute
