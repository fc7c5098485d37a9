// Packages of format_version 1 read into today's named held-out figures: every
// length version 1 wrote (4, 6, 7, 8 or 11 figures; 4 or 6 percentiles), and
// one-line errors for lengths no writer made.

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/package.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <numeric>

namespace phasecast {
namespace {

using ::testing::HasSubstr;

class PackageUpgrade : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    path_ = dir_ / "v1.h5";
    core::write_package(testing::make_plate_package(), path_);
    core::h5::File::open_write(path_).write_attribute("format_version", std::int32_t{1});
  }

  // The version-1 datasets: figure i reads (i + 1) / 100, percentile j (j + 1) / 1000.
  void write_v1(int figures, int percentiles, int curve) {
    auto f = core::h5::File::open_write(path_);
    f.write("/appearance/held_out_nodes", std::vector<std::int32_t>{1, 2});
    f.write("/appearance/held_out_error", counting(figures, 100));
    if (percentiles > 0) f.write("/appearance/held_out_spread", counting(percentiles, 1000));
    if (curve > 0) f.write("/appearance/held_out_truncation_curve", std::vector<float>(curve, 0.0f));
  }

  template <class T>
  void rewrite(const std::string& name, const std::vector<T>& values) {
    auto f = core::h5::File::open_write(path_);
    f.remove(name);
    f.write(name, values);
  }

  static std::vector<float> counting(int n, float scale) {
    std::vector<float> v(n);
    std::iota(v.begin(), v.end(), 1.0f);
    for (float& x : v) x /= scale;
    return v;
  }

  std::filesystem::path dir_, path_;
};

TEST_F(PackageUpgrade, EveryVersionOneLengthReadsByName) {
  for (const int figures : {4, 6, 7, 8, 11}) {
    SetUp();
    write_v1(figures, figures >= 6 ? (figures == 11 ? 6 : 4) : 0, 0);
    const auto p = core::read_package(path_);
    EXPECT_EQ(p.attributes.format_version, core::kFormatVersion);
    ASSERT_TRUE(p.appearance->held_out) << figures;
    const core::HeldOutFigures& h = *p.appearance->held_out;
    EXPECT_EQ(h.nodes, (std::vector<std::int32_t>{1, 2}));
    EXPECT_FLOAT_EQ(h.total, 0.01f);
    EXPECT_FLOAT_EQ(h.truncation, 0.02f);
    EXPECT_FLOAT_EQ(h.interpolation, 0.03f);
    EXPECT_FLOAT_EQ(h.of_transfer, 0.04f);
    EXPECT_EQ(h.l2_total.has_value(), figures >= 6);
    if (figures >= 6) {
      EXPECT_FLOAT_EQ(*h.l2_truncation, 0.06f);
    }
    EXPECT_EQ(h.clusters_l2_truncation.has_value(), figures >= 7);
    if (figures >= 7) {
      EXPECT_FLOAT_EQ(*h.clusters_l2_truncation, 0.07f);
    }
    EXPECT_EQ(h.l2_floor.has_value(), figures >= 8);
    if (figures >= 8) {
      EXPECT_FLOAT_EQ(*h.l2_floor, 0.08f);
    }
    EXPECT_EQ(h.l2_floor_of_variation.has_value(), figures == 11);
    if (figures == 11) {
      EXPECT_FLOAT_EQ(*h.of_variation, 0.09f);
      EXPECT_FLOAT_EQ(*h.l2_of_variation, 0.10f);
      EXPECT_FLOAT_EQ(*h.l2_floor_of_variation, 0.11f);
      EXPECT_FLOAT_EQ(h.l2_of_variation_spread->p10, 0.005f);
      EXPECT_FLOAT_EQ(h.l2_of_variation_spread->p90, 0.006f);
    }
    EXPECT_EQ(h.l2_total_spread.has_value(), figures >= 6);
    if (figures >= 6) {
      EXPECT_FLOAT_EQ(h.l2_total_spread->p90, 0.002f);
      EXPECT_FLOAT_EQ(h.l2_truncation_spread->p10, 0.003f);
    }
    EXPECT_EQ(h.l2_of_variation_spread.has_value(), figures == 11);
    // Written again, the package is today's version with the same figures.
    core::write_package(p, dir_ / "v2.h5");
    const auto again = core::read_package(dir_ / "v2.h5");
    EXPECT_EQ(again.appearance->held_out->l2_floor, h.l2_floor);
    EXPECT_EQ(core::h5::File::open_read(dir_ / "v2.h5").read_attribute_number("format_version"),
              core::kFormatVersion);
  }
}

TEST_F(PackageUpgrade, WithoutFiguresThereIsNoHeldOutTruth) {
  EXPECT_FALSE(core::read_package(path_).appearance->held_out);
}

TEST_F(PackageUpgrade, LengthsNoVersionOneWriterMadeAreOneLineErrors) {
  for (const int figures : {0, 5, 9, 12}) {
    SetUp();
    write_v1(figures, 0, 0);
    EXPECT_THAT(testing::package_rejection(path_),
                HasSubstr(fmt::format("/appearance/held_out_error: expected 4, 6, 7, 8 or 11 figures "
                                      "(format_version 1), got {}",
                                      figures)));
  }
  SetUp();
  write_v1(11, 3, 0);
  EXPECT_THAT(
      testing::package_rejection(path_),
      HasSubstr("/appearance/held_out_spread: expected 4 or 6 percentiles (format_version 1), got 3"));
  SetUp();
  core::h5::File::open_write(path_).write("/appearance/held_out_spread", counting(4, 1000));
  EXPECT_THAT(testing::package_rejection(path_),
              HasSubstr("/appearance/held_out_spread: expected /appearance/held_out_error beside it"));
  SetUp();
  write_v1(11, 6, 99);  // more directions than the plate's clusters resolve: named as the file has it
  EXPECT_THAT(testing::package_rejection(path_),
              HasSubstr("/appearance/held_out_truncation_curve: expected at least r_a = "));
  SetUp();
  write_v1(11, 6, 0);
  std::vector<float> figures(11, 0.1f);
  figures[6] = NAN;
  rewrite("/appearance/held_out_error", figures);
  EXPECT_THAT(testing::package_rejection(path_),
              HasSubstr("/appearance/held_out_error: expected finite errors >= 0, got nan at 6"));
  SetUp();
  write_v1(4, 0, 0);
  rewrite("/appearance/held_out_nodes", std::vector<std::int32_t>{1, 999999});
  EXPECT_THAT(testing::package_rejection(path_),
              HasSubstr("/appearance/held_out_nodes: expected state nodes in [0, "));
}

}  // namespace
}  // namespace phasecast
