// The orbit store round-trips exactly and rejects files that are not orbit stores.

#include "phasecast/precompute/sampling/orbit_store.h"
#include "error_of.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "run_tool.h"
#include "source_tree.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>

#include <cmath>

namespace phasecast::precompute {
namespace {

using phasecast::testing::error_of;

const std::filesystem::path kScenes = phasecast::testing::scenes_dir();

OrbitStore tiny_orbit() {
  const Scene s = load_scene_file(kScenes / "tiny/cloth_door.toml");
  return simulate_schedule(s, parse_schedule("open 0.3; stop 0.2", s));
}

TEST(OrbitStore, RoundTripsExactly) {
  const OrbitStore a = tiny_orbit();
  ASSERT_EQ(a.frames(), 25);
  EXPECT_EQ(a.irf_start, (std::vector<std::int32_t>{0, 15}));
  EXPECT_EQ(a.irf_length, (std::vector<std::int32_t>{15, 10}));
  EXPECT_EQ(a.irf_palette, (std::vector<std::int32_t>{2, 1}));
  const auto path = testing::scratch_dir("orbit_roundtrip") / "run.h5";
  write_orbit_store(a, path);
  const OrbitStore b = read_orbit_store(path);
  EXPECT_EQ(b.scene, "cloth_door_tiny");
  EXPECT_EQ(b.dt, a.dt);
  EXPECT_EQ(b.positions, a.positions);
  EXPECT_EQ(b.velocities, a.velocities);
  EXPECT_EQ(b.support, a.support);
  EXPECT_EQ(b.triangles, a.triangles);
  EXPECT_EQ(b.pinned, a.pinned);
  EXPECT_EQ(b.frame_palette, a.frame_palette);
  EXPECT_EQ(b.palette_names, a.palette_names);
  EXPECT_EQ(b.alpha_forcing, a.alpha_forcing);
  ASSERT_EQ(b.kinematics.size(), 3u);
  EXPECT_TRUE(b.kinematics[2].rotational);
  EXPECT_FLOAT_EQ(b.kinematics[2].rate, 1.5f);
}

TEST(OrbitStore, FirstFrameOfAnIrfCarriesTheImpulse) {
  const OrbitStore a = tiny_orbit();
  // Frame 0 starts the door: the free cloth lags behind it, pinned vertices do not move.
  double free_speed = 0, pinned_speed = 0;
  for (int i = 0; i < a.vertices(); ++i) {
    const double speed = a.velocities.block(0, 3 * i, 1, 3).norm();
    (a.pinned[static_cast<size_t>(i)] ? pinned_speed : free_speed) += speed;
  }
  EXPECT_GT(free_speed, 0.1);
  EXPECT_EQ(pinned_speed, 0.0);
}

TEST(OrbitStoreErrors, MissingFile) {
  EXPECT_EQ(error_of([] { read_orbit_store("/nonexistent/run.h5"); }), "/nonexistent/run.h5: no such file");
}

TEST(OrbitStoreErrors, ScenePackageIsNotAnOrbitStore) {
  const auto path = testing::scratch_dir("orbit_not") / "package.h5";
  core::write_package(testing::make_plate_package(), path);
  EXPECT_EQ(error_of([&] { read_orbit_store(path); }),
            path.string() + ": / attribute format: expected \"phasecast-orbits\" (is this an orbit store?)");
}

TEST(OrbitStoreErrors, IrfsMustTileTheFrames) {
  OrbitStore a = tiny_orbit();
  a.irf_start[1] = 14;
  EXPECT_EQ(
      error_of([&] { validate_orbit_store(a, "x.h5"); }),
      "x.h5: /irfs/start: IRF 1 must start at frame 15 with length >= 1 (IRFs tile the frames in order)");
}

TEST(OrbitStoreErrors, NaNFramesAreRejected) {
  OrbitStore a = tiny_orbit();
  a.positions(3, 4) = std::nanf("");
  EXPECT_EQ(error_of([&] {
              write_orbit_store(a, testing::scratch_dir("orbit_nan") / "x.h5");
            }).find(": /frames/positions: NaN or Inf in the frames") != std::string::npos,
            true);
}

}  // namespace
}  // namespace phasecast::precompute
