// The stable neo-Hookean tetrahedron (Smith, de Goes & Kim 2018) against
// independent truths: central differences of its energy and forces, linear
// elasticity at small strain, and its defining behaviour through inversion.

#include "phasecast/precompute/simulation/elastic_forces.h"
#include "phasecast/precompute/simulation/scene.h"
#include "phasecast/precompute/simulation/simulator.h"
#include "phasecast/precompute/simulation/tet_quality.h"
#include "run_tool.h"
#include "source_tree.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <cmath>
#include <fstream>
#include <random>
#include <regex>

namespace phasecast::precompute {
namespace {

using Eigen::Matrix3d;
using Matrix12d = Eigen::Matrix<double, 12, 12>;

const Lame kLame{1.0, 3.0};  // Pa; any pair, unitless in these checks

// One stable neo-Hookean tet with a general (not right-angled) rest shape.
DeformableModel one_tet(Lame lame = kLame) {
  DeformableModel m;
  m.rest.resize(12);
  m.rest << 0.1, 0, 0, 1, 0.1, 0, 0.2, 0.9, 0.1, 0.3, 0.2, 1.1;
  m.mass = Eigen::Vector4d::Constant(1.0);
  m.pinned.assign(4, 0);
  add_tet(m, {0, 1, 2, 3}, lame, TetEnergy::stable_neo_hookean);
  return m;
}

// Corner positions x = F X + t of the rest corners X.
Eigen::VectorXd deformed(const DeformableModel& m, const Matrix3d& F) {
  Eigen::VectorXd x(m.rest.size());
  for (int i = 0; i < m.vertices(); ++i)
    x.segment<3>(3 * i) = F * m.rest.segment<3>(3 * i) + Eigen::Vector3d(0.3, -0.2, 0.1);
  return x;
}

double det_F(const TetElement& t, const Eigen::VectorXd& x) {
  Matrix3d Ds;
  for (int k = 0; k < 3; ++k) Ds.col(k) = x.segment<3>(3 * t.v[k + 1]) - x.segment<3>(3 * t.v[0]);
  return (Ds * t.Dm_inv).determinant();
}

Matrix12d stiffness(const DeformableModel& m, const Eigen::VectorXd& x) {
  const auto eval = evaluate_elastic(m, x, true);
  Eigen::SparseMatrix<double> K(12, 12);
  K.setFromTriplets(eval.stiffness.begin(), eval.stiffness.end());
  return Matrix12d(K);
}

// summarize_tets on frames of known F: det F is the tet's J in every frame.
TEST(TetQuality, FindsTheLeastDetFAndCountsFramesWithAnInvertedTet) {
  const DeformableModel m = one_tet();
  const std::vector<Matrix3d> F = {Matrix3d::Identity(), Eigen::Vector3d(1, 1, -0.5).asDiagonal(),
                                   Eigen::Vector3d(0.9, 1, 0.8).asDiagonal(),
                                   Eigen::Vector3d(1, -2, 1).asDiagonal()};
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> frames(4, 12);
  for (int f = 0; f < 4; ++f)
    frames.row(f) = deformed(m, F[static_cast<size_t>(f)]).cast<float>().transpose();
  const TetSummary s = summarize_tets(m, frames);
  EXPECT_EQ(s.frames, 4);
  EXPECT_EQ(s.frames_inverted, 2);  // J = -0.5 and -2
  EXPECT_NEAR(s.least_j, -2, 1e-5);
  EXPECT_EQ(s.least_frame, 3);
  EXPECT_EQ(s.least_tet, 0);
  const TetSummary upright = summarize_tets(m, frames.topRows(1));
  EXPECT_NEAR(upright.least_j, 1, 1e-5);
  EXPECT_EQ(upright.frames_inverted, 0);
  EXPECT_EQ(summarize_tets(m, frames.topRows(0)).least_tet, -1);  // no frame: nothing measured
}

// Minus the central-difference derivative of the forces: the energy's Hessian.
Matrix12d numeric_hessian(const DeformableModel& m, const Eigen::VectorXd& x) {
  const double eps = 1e-6;
  Matrix12d H;
  for (int j = 0; j < 12; ++j) {
    Eigen::VectorXd xp = x, xm = x;
    xp[j] += eps;
    xm[j] -= eps;
    H.col(j) = -(evaluate_elastic(m, xp, false).force - evaluate_elastic(m, xm, false).force) / (2 * eps);
  }
  return 0.5 * (H + H.transpose());
}

Matrix3d random_F(std::mt19937& rng, double spread) {
  std::normal_distribution<double> n(0.0, spread);
  Matrix3d F = Matrix3d::Identity();
  for (int k = 0; k < 9; ++k) F(k % 3, k / 3) += n(rng);
  return F;
}

TEST(StableNeoHookean, ForcesAreEnergyGradientsAlsoWhenInverted) {
  const DeformableModel m = one_tet();
  std::mt19937 rng(3);
  int inverted = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::VectorXd x = deformed(m, random_F(rng, 0.6));
    inverted += det_F(m.tets[0], x) < 0;
    const auto eval = evaluate_elastic(m, x, false);
    for (int i = 0; i < 12; ++i) {
      const double eps = 1e-6;
      Eigen::VectorXd xp = x, xm = x;
      xp[i] += eps;
      xm[i] -= eps;
      const double numeric =
          -(evaluate_elastic(m, xp, false).energy - evaluate_elastic(m, xm, false).energy) / (2 * eps);
      EXPECT_NEAR(eval.force[i], numeric, 1e-6 * (1 + std::abs(numeric)))
          << "trial " << trial << " coordinate " << i;
    }
  }
  EXPECT_GT(inverted, 0);  // the trials did include inverted tets
}

TEST(StableNeoHookean, StiffnessIsTheHessianWhereThatIsPositiveDefinite) {
  const DeformableModel m = one_tet();
  std::mt19937 rng(5);
  // Stretched by 4 % (J = 1.125): lambda' (J - 1) - mu ~ -mu/2 with lambda' = 4, where the Hessian in F is
  // definite.
  const Eigen::VectorXd x =
      deformed(m, 1.04 * Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).matrix() +
                      0.002 * (random_F(rng, 1.0) - Matrix3d::Identity()));
  const Matrix12d K = stiffness(m, x), H = numeric_hessian(m, x);
  EXPECT_LT((K - K.transpose()).cwiseAbs().maxCoeff(), 1e-12 * K.cwiseAbs().maxCoeff());
  EXPECT_LT((K - H).cwiseAbs().maxCoeff(), 1e-6 * H.cwiseAbs().maxCoeff()) << "K\n" << K << "\nH\n" << H;
}

TEST(StableNeoHookean, StiffnessIsSymmetricPositiveSemiDefiniteEverywhere) {
  const DeformableModel m = one_tet();
  std::mt19937 rng(7);
  int indefinite_hessians = 0;
  for (int trial = 0; trial < 30; ++trial) {
    const Eigen::VectorXd x = deformed(m, random_F(rng, 0.5));
    const Matrix12d K = stiffness(m, x);
    const double scale = K.cwiseAbs().maxCoeff();
    EXPECT_LT((K - K.transpose()).cwiseAbs().maxCoeff(), 1e-12 * scale);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix12d>(K).eigenvalues().minCoeff(), -1e-10 * scale) << trial;
    indefinite_hessians +=
        Eigen::SelfAdjointEigenSolver<Matrix12d>(numeric_hessian(m, x)).eigenvalues().minCoeff() <
        -1e-3 * scale;
  }
  EXPECT_GT(indefinite_hessians, 0);  // the projection had work to do
}

TEST(StableNeoHookean, InvertedTetIsFiniteAndPushedBackToItsRestVolume) {
  const DeformableModel m = one_tet({1e3, 3e3});
  // The apex pushed through its opposite face: J = -0.5.
  const Eigen::VectorXd x = deformed(m, Eigen::Vector3d(1, 1, -0.5).asDiagonal().toDenseMatrix());
  ASSERT_NEAR(det_F(m.tets[0], x), -0.5, 1e-12);
  const auto eval = evaluate_elastic(m, x, false);
  EXPECT_TRUE(std::isfinite(eval.energy));
  EXPECT_TRUE(eval.force.allFinite());
  const Eigen::VectorXd pushed = x + 1e-6 * eval.force;  // a small step along the force
  EXPECT_GT(det_F(m.tets[0], pushed), det_F(m.tets[0], x));
  EXPECT_LT(evaluate_elastic(m, pushed, false).energy, eval.energy);
  // Left to itself (damped, no gravity) it turns inside out again and comes to rest at its rest volume.
  SimulationSettings s;
  s.frame_dt = 0.01;
  s.gravity.setZero();
  s.mass_damping = 5;
  s.max_speed = 1e6;
  auto sim = make_implicit_simulator(m, s, {});
  SimState start = sim->rest_state();
  start.x = x;
  sim->reset(start);
  for (int i = 0; i < 400; ++i) sim->step(Eigen::Vector3d::Zero());
  EXPECT_NEAR(det_F(m.tets[0], sim->state().x), 1.0, 1e-3);
}

// Linear elasticity: sigma = lambda tr(eps) I + 2 mu eps, forces -V sigma G^T on the corners.
Eigen::VectorXd linear_forces(const TetElement& t, const Matrix3d& eps) {
  const Lame& l = t.lame;
  const Matrix3d sigma = l.lambda * eps.trace() * Matrix3d::Identity() + 2 * l.mu * eps;
  Eigen::Matrix<double, 4, 3> G;
  G.bottomRows<3>() = t.Dm_inv;
  G.row(0) = -t.Dm_inv.colwise().sum();
  const Eigen::Matrix<double, 3, 4> f = -t.volume * sigma * G.transpose();
  return Eigen::Map<const Eigen::VectorXd>(f.data(), 12);
}

TEST(StableNeoHookean, SmallStrainStressIsLinearElasticityWithTheSameLameParameters) {
  const DeformableModel m = one_tet(lame_from_young(2.5e4, 0.45));  // the toy's rubber
  const double e = 1e-5;
  Matrix3d uniaxial = Matrix3d::Identity(), shear = Matrix3d::Identity();
  uniaxial(0, 0) += e;
  shear(0, 1) += e;
  for (const Matrix3d& F : {uniaxial, shear}) {
    const Matrix3d eps = 0.5 * (F + F.transpose()) - Matrix3d::Identity();
    const Eigen::VectorXd expected = linear_forces(m.tets[0], eps);
    const Eigen::VectorXd got = evaluate_elastic(m, deformed(m, F), false).force;
    // Relative error O(strain): the nonlinear terms.
    EXPECT_LT((got - expected).cwiseAbs().maxCoeff(), 1e-3 * expected.cwiseAbs().maxCoeff())
        << "got " << got.transpose() << "\nexpected " << expected.transpose();
  }
}

// The tiny toy with its rubber as stable neo-Hookean, read from a scene file.
std::filesystem::path neo_hookean_toy() {
  std::string text = testing::read_file(phasecast::testing::scenes_dir() / "tiny/toy_dashboard.toml");
  text = std::regex_replace(text, std::regex(R"(energies = \["tet_fem"\])"),
                            R"(energies = ["tet_neo_hookean"])");
  text =
      std::regex_replace(text, std::regex(R"(path = "\.\./meshes/)"),
                         std::string("path = \"") + phasecast::testing::scenes_dir().string() + "/meshes/");
  const auto path = testing::scratch_dir("neo_hookean_toy") / "toy.toml";
  std::ofstream(path) << text;
  return path;
}

TEST(StableNeoHookean, ToySceneParsesAndAJoltStaysFiniteWithNoInvertedTet) {
  const Scene scene = load_scene_file(neo_hookean_toy());
  ASSERT_GT(scene.model.tets.size(), 60u);
  for (const auto& t : scene.model.tets) ASSERT_EQ(t.energy, TetEnergy::stable_neo_hookean);
  auto sim = make_simulator(scene);
  const auto& forward = scene.palette.at(static_cast<size_t>(scene.palette_index("forward")));
  sim->impulse(forward.alpha_impulse);
  double wobble = 0, least_J = 1e300;
  for (int f = 0; f < 30; ++f) {
    sim->step(forward.alpha_forcing);
    ASSERT_TRUE(sim->state().x.allFinite() && sim->state().v.allFinite()) << "frame " << f;
    for (const auto& t : scene.model.tets) least_J = std::min(least_J, det_F(t, sim->state().x));
    wobble = std::max(wobble, (sim->state().x - scene.model.rest).cwiseAbs().maxCoeff());
  }
  std::printf("neo-Hookean toy jolt: largest displacement %.4f m, least J %.3f\n", wobble, least_J);
  EXPECT_GT(least_J, 0);
  EXPECT_GT(wobble, 0.002);  // it did wobble
}

}  // namespace
}  // namespace phasecast::precompute
