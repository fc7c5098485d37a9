// phasecast-precompute check's findings against cases whose answer is known:
// a rigid motion in closed form, a flag on a pole (a neutral turn about the
// pole) and the tiny cloth door (which returns to its rest).

#include "phasecast/precompute/pipeline/scene_check.h"
#include "source_tree.h"

#include <gtest/gtest.h>

#include <algorithm>

#include <Eigen/Geometry>

#include <numbers>

namespace phasecast::precompute {
namespace {

TEST(SceneCheck, RigidFitRecoversATurnAboutAnAxisAndASlideAlongIt) {
  Eigen::MatrixX3d from(5, 3);
  from << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0.3, 0.7, 0.2;
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 2).normalized(), through(0.5, -1, 2);
  const double angle = 40 * std::numbers::pi / 180, slide = 0.25;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
  Eigen::MatrixX3d to(5, 3);
  for (int i = 0; i < 5; ++i)
    to.row(i) = (R * (from.row(i).transpose() - through) + through + slide * axis).transpose();
  const RigidMotion m = fit_rigid_motion(from, to);
  EXPECT_NEAR(m.angle_deg, 40, 1e-9);
  EXPECT_LT((m.axis - axis).norm(), 1e-9);
  EXPECT_LT((m.translation - slide * axis).norm(), 1e-9);
  // The reported point lies on the true axis.
  EXPECT_LT(((m.through - through) - (m.through - through).dot(axis) * axis).norm(), 1e-9);
  EXPECT_LT(m.residual, 1e-12);
}

// A slide in float32 positions has a turn of noise: it stays a slide, of the right length.
TEST(SceneCheck, RigidFitTakesANoisySlideForASlide) {
  Eigen::MatrixX3d from(6, 3);
  from << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0.3, 0.7, 0.2, 0.9, 0.1, 0.5;
  Eigen::MatrixX3d to = from.rowwise() + Eigen::RowVector3d(0.1, 0, 0.05);
  to = to.cast<float>().cast<double>();  // as an orbit store holds them
  const RigidMotion m = fit_rigid_motion(from, to);
  EXPECT_LT(m.angle_deg, 0.01);
  EXPECT_LT((m.translation - Eigen::Vector3d(0.1, 0, 0.05)).norm(), 1e-6);
  EXPECT_LT(m.residual, 1e-6);
}

TEST(SceneCheck, NamesTheNeutralTurnOfAFlagAboutItsPole) {
  const Scene scene = load_scene_file(testing::source_dir() / "tests/data/scenes/flag_pole.toml");
  const SceneCheck c = check_scene(scene, nullptr, {});
  EXPECT_EQ(c.quiet, "stop");
  ASSERT_TRUE(c.rest);
  EXPECT_FALSE(c.rest->displaced || c.rest->moving);
  ASSERT_EQ(c.returns.size(), 1u);
  const RestTrial& t = c.returns[0];
  EXPECT_TRUE(t.displaced);
  EXPECT_FALSE(t.moving);
  EXPECT_GT(t.max_displacement, 0.2);
  ASSERT_TRUE(t.rigid && t.rigid->explains);
  EXPECT_EQ(t.rigid->body, "flag");
  EXPECT_GT(t.rigid->angle_deg, 20);
  EXPECT_GT(std::abs(t.rigid->axis.y()), 0.9) << "turned about the vertical pole";
  EXPECT_LT(Eigen::Vector2d(t.rigid->through.x(), t.rigid->through.z()).norm(), 0.05) << "through the pole";
  EXPECT_EQ(c.problems(), 1);
  const auto lines = c.report({});
  EXPECT_NE(lines.back().find("a neutral mode: 'flag' turned"), std::string::npos) << lines.back();
}

// Without a quiet entry, each jolt is followed by its own quiet time.
TEST(SceneCheck, TheTinyToysJoltsEachReturnToRest) {
  const Scene scene = load_scene_file(testing::source_dir() / "scenes/tiny/toy_dashboard.toml");
  const SceneCheck c = check_scene(scene, nullptr, {});
  EXPECT_TRUE(c.quiet.empty());
  EXPECT_FALSE(c.rest);
  ASSERT_EQ(c.returns.size(), 5u);  // forward, back, left, right, up
  for (const auto& t : c.returns) {
    EXPECT_FALSE(t.moving || t.displaced)
        << t.schedule << ": " << t.max_displacement << " m, " << t.max_speed;
  }
  EXPECT_EQ(c.problems(), 0);
}

TEST(SceneCheck, TheTinyClothDoorReturnsToItsRest) {
  const Scene scene = load_scene_file(testing::source_dir() / "scenes/tiny/cloth_door.toml");
  const SceneCheck c = check_scene(scene, nullptr, {});
  ASSERT_EQ(c.returns.size(), 2u);  // open and close, each then stop
  // 'close' moves nothing from the rest (the door is at the end of its
  // range): it is played after an 'open' and a stop.
  EXPECT_EQ(c.returns[0].schedule, "open 0.62; stop 3.00; close 0.62; stop 3.00");
  EXPECT_EQ(c.returns[1].schedule, "open 0.62; stop 3.00");
  for (const auto& t : c.returns) {
    EXPECT_LT(t.max_displacement, 0.02 * c.radius) << t.schedule;
    EXPECT_GT(t.peak_displacement, 0.02 * c.radius) << t.schedule << ": the trial moved the cloth";
  }
  EXPECT_TRUE(c.unplayable.empty());
  EXPECT_EQ(c.problems(), 0);
}

// Stops too short for the towel to settle: each return still moves at its
// end, a problem named with its fix.
TEST(SceneCheck, AStopTooShortToSettleIsNamed) {
  const Scene scene = load_scene_file(testing::source_dir() / "scenes/tiny/cloth_door.toml");
  SceneCheckOptions o;
  o.stop_seconds = 0.1;
  const SceneCheck c = check_scene(scene, nullptr, o);
  ASSERT_EQ(c.returns.size(), 2u);
  for (const auto& t : c.returns) EXPECT_TRUE(t.moving) << t.schedule;
  EXPECT_EQ(c.problems(), 2);
  const auto lines = c.report(o);
  const auto moving = std::count_if(lines.begin(), lines.end(), [](const std::string& l) {
    return l.find("still moving at") != std::string::npos &&
           l.find("fix: longer quiet entries (t_min, t_max) or more damping") != std::string::npos;
  });
  EXPECT_EQ(moving, 2);
}

}  // namespace
}  // namespace phasecast::precompute
