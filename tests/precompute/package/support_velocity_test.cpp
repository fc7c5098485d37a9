// The support velocities the package's IRF cache keys on (package_builder.h):
// taken over the whole orbit store, then cut to the kept IRFs.

#include "phasecast/precompute/package/package_builder.h"
#include "scene_files.h"

#include <gtest/gtest.h>

namespace phasecast::precompute {
namespace {

// The tiny door's palette: close (+1.5 rad/s about y), stop, open (-1.5).
// IRFs: close (nodes 0-2), a stop after it (3-4), open from rest (5-6), a
// stop after it (7-8). With only the stops kept, each still starts at the
// velocity of the dropped IRF it continues: cut first, the first stop would
// continue nothing, the second the first, and both would start still.
TEST(KeptSupportVelocities, AKeptIrfStartsAtTheVelocityOfTheDroppedOneItContinues) {
  const Scene scene = load_scene_file(testing::tiny_scene_path());
  ASSERT_EQ(scene.palette.size(), 3u);
  IrfList irfs;
  irfs.start = {0, 3, 5, 7};
  irfs.length = {3, 2, 2, 2};
  irfs.palette = {0, 1, 2, 1};
  irfs.continues = {0, 1, 0, 1};
  const std::vector<SupportVelocity> want = {{0, 1.5, 0}, {0, 0, 0}, {0, -1.5, 0}, {0, 0, 0}};
  EXPECT_EQ(kept_support_velocities(scene, irfs, {1, 3}), want);
  // All kept: every node, the open from rest starting still.
  const auto all = kept_support_velocities(scene, irfs, {0, 1, 2, 3});
  ASSERT_EQ(all.size(), 9u);
  EXPECT_EQ(all[0], (SupportVelocity{0, 0, 0}));
  EXPECT_EQ(all[1], (SupportVelocity{0, 1.5, 0}));
  EXPECT_EQ(all[5], (SupportVelocity{0, 0, 0}));
  EXPECT_EQ(all[6], (SupportVelocity{0, -1.5, 0}));
}

}  // namespace
}  // namespace phasecast::precompute
