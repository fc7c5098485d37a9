// Writing and reading a package reproduces it exactly; writes are atomic.

#include "phasecast/core/basis.h"
#include "phasecast/core/hash.h"
#include "phasecast/core/package.h"
#include "run_tool.h"
#include "same_package.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>
#include <thread>

namespace phasecast {
namespace {

using core::ScenePackage;

using testing::expect_same_package;

TEST(PackageRoundTrip, WithAppearanceIsExact) {
  const auto dir = testing::scratch_dir("roundtrip_appearance");
  const ScenePackage written = testing::make_plate_package();
  core::write_package(written, dir / "plate.h5");
  expect_same_package(written, core::read_package(dir / "plate.h5"));
}

TEST(PackageRoundTrip, WithoutAppearanceIsExact) {
  const auto dir = testing::scratch_dir("roundtrip_plain");
  testing::PlateOptions o;
  o.appearance = false;
  const ScenePackage written = testing::make_plate_package(o);
  core::write_package(written, dir / "plate.h5");
  const ScenePackage read = core::read_package(dir / "plate.h5");
  expect_same_package(written, read);
  EXPECT_EQ(read.rank_a(), 0);
  EXPECT_EQ(read.portrait.q_a.cols(), 0);
}

TEST(PackageRoundTrip, WriteIsAtomicAndLeavesNoTemporaryFile) {
  const auto dir = testing::scratch_dir("roundtrip_atomic");
  core::write_package(testing::make_plate_package(), dir / "plate.h5");
  // Overwriting an existing package with an invalid one is refused before any
  // byte is written: the old package stays readable.
  ScenePackage bad = testing::make_plate_package();
  bad.portrait.irf_palette[0] = 7;
  EXPECT_THROW(core::write_package(bad, dir / "plate.h5"), core::PackageError);
  EXPECT_NO_THROW(core::read_package(dir / "plate.h5"));
  int files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1);
}

TEST(PackageRoundTrip, SamePackageGivesTheSameBytes) {
  // Recordings and clients name packages by content hash: writing must be deterministic.
  const auto dir = testing::scratch_dir("roundtrip_bytes");
  core::write_package(testing::make_plate_package(), dir / "a.h5");
  // HDF5 stamps object headers in whole seconds unless told not to: writing the
  // second copy in a later second makes a stamped header show, every time.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  core::write_package(testing::make_plate_package(), dir / "b.h5");
  EXPECT_EQ(core::file_content_hash(dir / "a.h5"), core::file_content_hash(dir / "b.h5"));
}

TEST(PackageRoundTrip, FixtureIsAConsistentPhasePortrait) {
  const ScenePackage p = testing::make_plate_package();
  // U_u orthonormal (eq. 4) and Q_u = S V^T: columns of q_u orthogonal with norms sigma (eq. 6).
  const Eigen::MatrixXf UtU = p.reduction.U_u.transpose() * p.reduction.U_u;
  EXPECT_TRUE(UtU.isIdentity(1e-4f));
  const Eigen::MatrixXf QtQ = p.portrait.q_u.transpose() * p.portrait.q_u;
  for (int i = 0; i < p.rank_u(); ++i) {
    EXPECT_NEAR(std::sqrt(QtQ(i, i)), p.reduction.singular_values[i], 1e-3f * p.reduction.singular_values[0]);
  }
  // The nearest-IRF cache of an IRF's own start node is that IRF (distance 0).
  for (int i = 0; i < p.portrait.irf_count(); ++i) {
    const int start = p.portrait.irf_start[static_cast<size_t>(i)];
    const int d = p.portrait.irf_palette[static_cast<size_t>(i)];
    EXPECT_EQ(p.portrait.irf_start[static_cast<size_t>(p.portrait.nearest_irf(start, d))], start);
  }
  EXPECT_GT(p.rank_a(), 0);
}

TEST(BasisParts, CoverEverythingAThinClientNeeds) {
  const ScenePackage p = testing::make_plate_package();
  const auto parts = core::basis_parts(p);
  ASSERT_EQ(parts.size(), 8u);
  EXPECT_EQ(parts[5].name, "U_u");
  EXPECT_EQ(parts[5].bytes.size(), sizeof(float) * 3 * p.mesh.points() * p.rank_u());
  EXPECT_EQ(parts[7].shape,
            (std::vector<std::uint64_t>{48u * p.mesh.points(), static_cast<std::uint64_t>(p.rank_a())}));
  EXPECT_EQ(core::reduced_state_bytes(p), sizeof(float) * (p.rank_u() + p.rank_a() + 12));
}

}  // namespace
}  // namespace phasecast
