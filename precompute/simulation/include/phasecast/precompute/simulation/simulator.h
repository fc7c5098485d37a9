#pragma once
// The offline simulator: the paper's "black box" (§3). The sampler drives any
// Simulator through this interface and knows nothing of its internals; the
// engine knows nothing of IRFs.

#include "phasecast/precompute/simulation/deformable_model.h"
#include "phasecast/precompute/simulation/support_motion.h"

#include <Eigen/Core>

#include <memory>
#include <stdexcept>

namespace phasecast::precompute {

// Raised for invalid simulator input (wrong palette parameter size, NaN, ...).
class SimulationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct SimState {
  Eigen::VectorXd x;  // 3V positions, support frame
  Eigen::VectorXd v;  // 3V velocities relative to the support frame
  double time = 0;
  SupportState support;
};

class Simulator {
 public:
  virtual ~Simulator() = default;

  virtual int vertices() const = 0;
  virtual double frame_dt() const = 0;  // seconds advanced by one step()
  virtual int alpha_size() const = 0;   // k, the size of the palette parameter

  virtual SimState rest_state() const = 0;
  virtual void reset(const SimState& state) = 0;
  virtual const SimState& state() const = 0;

  // Starts a palette entry with its impulse parameter alpha_I.
  virtual void impulse(const Eigen::VectorXd& alpha_impulse) = 0;
  // Advances one frame while the entry's forcing parameter alpha_F is held.
  virtual void step(const Eigen::VectorXd& alpha_forcing) = 0;
  // Support-to-world transform (3x4) of the current state.
  virtual Eigen::Matrix<double, 3, 4> support_transform() const = 0;

  // Whether reset() takes any state, a checkpoint of another process's
  // included. A black box returns only to states it reached itself, so a
  // resumed chain is simulated again from its start.
  virtual bool restores_any_state() const { return true; }
};

// The sparse Cholesky of the implicit step: Eigen's simplicial LDL^T, fastest
// below a few thousand DOF, or CHOLMOD's supernodal LL^T (BLAS-3 on dense
// supernodes), about twice as fast at the paper's cloth size (docs/performance.md).
enum class LinearSolver { simplicial, supernodal };

// The implicit step: backward Euler in velocities (first order, damps the
// highest modes, the default), or Newmark's family, the integrator ABAQUS ran
// for the paper's solids, by default its average-acceleration member
// (gamma = 1/2, beta = 1/4: the trapezoidal rule, unconditionally stable with
// no numerical damping).
enum class Integrator { backward_euler, newmark };

struct SimulationSettings {
  double frame_dt = 1.0 / 50;
  int substeps = 2;
  int newton_iterations = 4;
  double newton_tolerance = 1e-7;  // m/s: stop when the largest velocity update is below
  Eigen::Vector3d gravity{0, -9.81, 0};
  double mass_damping = 0;       // Rayleigh a, 1/s
  double stiffness_damping = 0;  // Rayleigh b, s
  double max_speed = 50;         // m/s: particle speeds are clamped here (large impulses stay finite)
  double friction = 0.3;         // fraction of tangential velocity removed at an obstacle contact
  LinearSolver linear_solver = LinearSolver::simplicial;
  Integrator integrator = Integrator::backward_euler;
  double newmark_gamma = 0.5;  // unconditionally stable when gamma >= 1/2 and beta >= (gamma + 1/2)^2 / 4
  double newmark_beta = 0.25;
  double settle = 0;  // s of quasi-static relaxation before a recording starts (see orbit_recorder.h)
};

// Implicit backward Euler or Newmark (settings.integrator) with Newton
// iterations on the end-of-step velocities and a sparse Cholesky solve, in the
// frame of a moving support.
std::unique_ptr<Simulator> make_implicit_simulator(DeformableModel model, const SimulationSettings& settings,
                                                   const SupportSettings& support);

// Total mechanical energy in the support frame (kinetic + elastic + gravity), J.
double mechanical_energy(const DeformableModel& model, const SimulationSettings& settings,
                         const SimState& state);

}  // namespace phasecast::precompute
