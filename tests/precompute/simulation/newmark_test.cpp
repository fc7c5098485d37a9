// Newmark's average-acceleration rule against closed forms: on an undamped
// linear spring it keeps the energy (backward Euler loses it) and oscillates
// with the trapezoidal rule's discrete frequency (2/h) atan(omega h / 2).

#include "phasecast/precompute/simulation/elastic_forces.h"
#include "phasecast/precompute/simulation/simulator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

namespace phasecast::precompute {
namespace {

constexpr double kPi = 3.14159265358979323846;
const Eigen::VectorXd kNoAlpha = Eigen::VectorXd::Zero(3);

// A particle of mass m hanging on a rod of stiffness k (EA / l0, l0 = 1 m) from
// a pinned particle, no gravity: a linear spring along y, omega = sqrt(k / m).
struct Spring {
  double k = 400, mass = 0.25;
  double omega() const { return std::sqrt(k / mass); }  // 40 rad/s

  DeformableModel model() const {
    DeformableModel m;
    m.rest.resize(6);
    m.rest << 0, 0, 0, 0, -1, 0;
    m.mass = Eigen::Vector2d(mass, mass);
    m.pinned = {1, 0};
    add_rod_stretch(m, 0, 1, k);
    return m;
  }
};

SimulationSettings settings(Integrator integrator, double dt) {
  SimulationSettings s;
  s.frame_dt = dt;
  s.substeps = 1;
  s.newton_iterations = 8;
  s.newton_tolerance = 1e-12;
  s.gravity.setZero();
  s.max_speed = 1e9;
  s.integrator = integrator;
  return s;
}

// Runs `frames` frames from a 1 cm stretch; returns the stretch after each frame.
std::vector<double> stretch_history(const Spring& spring, const SimulationSettings& s, int frames,
                                    std::vector<double>* energy = nullptr) {
  const DeformableModel model = spring.model();
  auto sim = make_implicit_simulator(model, s, {});
  SimState start = sim->rest_state();
  start.x[4] -= 0.01;
  sim->reset(start);
  std::vector<double> y;
  for (int i = 0; i < frames; ++i) {
    sim->step(kNoAlpha);
    y.push_back(-(sim->state().x[4] + 1.0));
    if (energy) energy->push_back(mechanical_energy(model, s, sim->state()));
  }
  return y;
}

// Mean period from upward zero crossings (linear interpolation between frames).
double mean_period(const std::vector<double>& signal, double dt) {
  std::vector<double> times;
  for (size_t i = 1; i < signal.size(); ++i) {
    if (signal[i - 1] < 0 && signal[i] >= 0)
      times.push_back(dt * (static_cast<double>(i - 1) + signal[i - 1] / (signal[i - 1] - signal[i])));
  }
  EXPECT_GE(times.size(), 3u);
  return (times.back() - times.front()) / static_cast<double>(times.size() - 1);
}

TEST(Newmark, UndampedSpringKeepsItsEnergyWhereBackwardEulerLosesIt) {
  const Spring spring;
  const double period = 2 * kPi / spring.omega(), dt = period / 60;  // omega h = 0.105
  const double initial = 0.5 * spring.k * 0.01 * 0.01;               // J, from rest at 1 cm
  const int frames = 50 * 60;                                        // 50 periods
  std::vector<double> newmark, euler;
  stretch_history(spring, settings(Integrator::newmark, dt), frames, &newmark);
  stretch_history(spring, settings(Integrator::backward_euler, dt), frames, &euler);
  double drift = 0;
  for (double e : newmark) drift = std::max(drift, std::abs(e - initial) / initial);
  std::printf(
      "energy after 50 periods: newmark %.3e relative drift (largest), backward Euler %.3e of E0 left "
      "(after 1 period %.3f)\n",
      drift, euler.back() / initial, euler[59] / initial);
  // The trapezoidal rule keeps the quadratic energy of a linear system exactly; what is left is rounding
  // and the Newton tolerance.
  EXPECT_LT(drift, 1e-9);
  // Backward Euler's amplification 1 / sqrt(1 + (omega h)^2) per step: E falls by 1 / (1 + (omega h)^2)
  // a step, to exp(-60 ln(1.011)) = 0.52 of itself in one period.
  const double per_period = std::pow(1 + std::pow(spring.omega() * dt, 2), -60.0);
  EXPECT_NEAR(euler[59] / initial, per_period, 1e-9);
  EXPECT_LT(euler.back() / initial, 1e-6);
}

TEST(Newmark, PeriodIsTheTrapezoidalRulesDiscretePeriod) {
  const Spring spring;
  const double h = 0.5 / spring.omega();  // omega h = 0.5: the trapezoidal period is 2.05 % long
  const double exact = 2 * kPi / spring.omega();
  const double discrete = 2 * kPi / ((2 / h) * std::atan(spring.omega() * h / 2));
  const double measured = mean_period(stretch_history(spring, settings(Integrator::newmark, h), 1600), h);
  std::printf("period: exact %.6f s, trapezoidal closed form %.6f s, measured %.6f s\n", exact, discrete,
              measured);
  EXPECT_NEAR(measured, discrete, 1e-3 * discrete);
  EXPECT_GT(std::abs(measured - exact), 0.015 * exact);  // the test tells the two apart
}

TEST(Newmark, GammaAboveOneHalfDampsAndUnstableParametersAreRejected) {
  const Spring spring;
  const double dt = 2 * kPi / spring.omega() / 60;
  SimulationSettings s = settings(Integrator::newmark, dt);
  s.newmark_gamma = 0.625;
  s.newmark_beta = 0.31640625;  // (gamma + 1/2)^2 / 4
  std::vector<double> energy;
  stretch_history(spring, s, 600, &energy);
  std::printf("gamma 0.625: E after 10 periods %.3f of E0\n", energy.back() / energy.front());
  // Numerical damping of gamma > 1/2, ratio about (gamma - 1/2) omega h / 2: E to ~0.5 in 10 periods.
  EXPECT_LT(energy.back(), 0.7 * energy.front());
  EXPECT_GT(energy.back(), 0.3 * energy.front());
  s.newmark_beta = 0.25;
  try {
    make_implicit_simulator(spring.model(), s, {});
    FAIL() << "expected a rejection";
  } catch (const SimulationError& e) {
    EXPECT_STREQ(e.what(),
                 "simulation settings: expected newmark_gamma >= 1/2 and newmark_beta >= (newmark_gamma + "
                 "1/2)^2 / 4 (unconditionally stable Newmark), got 0.625, 0.25");
  }
}

// A nonlinear system: one free stable neo-Hookean tet released from a 10 %
// stretch, undamped (omega ~ 180 rad/s). The trapezoidal rule no longer keeps
// the energy exactly but stays within O(h^2) of it; backward Euler drains it.
TEST(Newmark, StretchedRubberTetKeepsItsEnergyToSecondOrder) {
  DeformableModel m;
  m.rest.resize(12);
  m.rest << 0, 0, 0, 0.1, 0, 0, 0, 0.1, 0, 0, 0, 0.1;
  m.mass = Eigen::Vector4d::Constant(0.05);
  m.pinned.assign(4, 0);
  add_tet(m, {0, 1, 2, 3}, lame_from_young(2.5e4, 0.45), TetEnergy::stable_neo_hookean);
  // Over 0.75 s (about 20 periods): the largest |E - E0| / E0, and E at the end / E0.
  const auto energy = [&m](Integrator integrator, double h) {
    SimulationSettings s = settings(integrator, h);
    s.newton_tolerance = 1e-10;
    auto sim = make_implicit_simulator(m, s, {});
    SimState start = sim->rest_state();
    start.x *= 1.1;
    sim->reset(start);
    const double e0 = mechanical_energy(m, s, start);
    double drift = 0;
    for (int i = 0; i < static_cast<int>(std::lround(0.75 / h)); ++i) {
      sim->step(kNoAlpha);
      drift = std::max(drift, std::abs(mechanical_energy(m, s, sim->state()) - e0) / e0);
    }
    return std::pair{drift, mechanical_energy(m, s, sim->state()) / e0};
  };
  const double coarse = energy(Integrator::newmark, 0.001).first,
               fine = energy(Integrator::newmark, 0.0005).first;
  const double euler = energy(Integrator::backward_euler, 0.0005).second;
  std::printf(
      "rubber tet: newmark largest energy drift %.2e (h = 1 ms), %.2e (h = 0.5 ms); backward Euler keeps "
      "%.4f of E0 (h = 0.5 ms)\n",
      coarse, fine, euler);
  EXPECT_LT(fine, 0.01);
  EXPECT_NEAR(coarse / fine, 4.0, 1.0);  // second order
  EXPECT_LT(euler, 0.1);
}

}  // namespace
}  // namespace phasecast::precompute
