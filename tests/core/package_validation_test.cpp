// Every rejection path of the package reader, each with its one-line message.

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/package.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

namespace phasecast {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::Not;

using testing::package_rejection;

class PackageFileRejection : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    path_ = dir_ / "plate.h5";
    core::write_package(testing::make_plate_package(), path_);
  }

  // Replaces dataset `name` with `values` of shape `dims`, bypassing validation.
  template <class T>
  void replace(const std::string& name, const std::vector<T>& values,
               const std::vector<std::uint64_t>& dims) {
    auto f = core::h5::File::open_write(path_);
    f.remove(name);
    f.write(name, values.data(), dims);
  }

  void remove(const std::string& name) { core::h5::File::open_write(path_).remove(name); }

  std::filesystem::path dir_, path_;
};

TEST_F(PackageFileRejection, ValidFileIsAccepted) {
  EXPECT_EQ(package_rejection(path_), "");
}

TEST_F(PackageFileRejection, MissingFile) {
  EXPECT_THAT(package_rejection(dir_ / "nope.h5"),
              AllOf(HasSubstr("nope.h5"), HasSubstr("no such package file")));
}

TEST_F(PackageFileRejection, NotHdf5) {
  std::ofstream(dir_ / "text.h5") << "this is not a package\n";
  EXPECT_THAT(package_rejection(dir_ / "text.h5"),
              AllOf(HasSubstr("text.h5"), HasSubstr("not an HDF5 file")));
}

TEST_F(PackageFileRejection, Truncated) {
  std::filesystem::resize_file(path_, std::filesystem::file_size(path_) / 2);
  EXPECT_THAT(package_rejection(path_), AllOf(HasSubstr("plate.h5"), HasSubstr("truncated")));
}

TEST_F(PackageFileRejection, CorruptedBulkDataFailsItsChecksum) {
  // Flip bytes inside U_u's raw data: the Fletcher-32 filter must catch it.
  const auto p = testing::make_plate_package();
  const float probe = p.reduction.U_u(3 * 5 + 2, 0);  // a non-zero entry
  std::fstream f(path_, std::ios::in | std::ios::out | std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(f)), {});
  const std::string needle(reinterpret_cast<const char*>(&probe), sizeof probe);
  const auto at = bytes.find(needle);
  ASSERT_NE(at, std::string::npos);
  f.seekp(static_cast<std::streamoff>(at));
  f.write("\x7f\x7f\x7f\x7f", 4);
  f.close();
  EXPECT_THAT(package_rejection(path_),
              AllOf(HasSubstr("plate.h5"), HasSubstr("/reduction/U_u"), HasSubstr("corrupt")));
}

TEST_F(PackageFileRejection, MissingDataset) {
  remove("/portrait/q_u");
  EXPECT_THAT(package_rejection(path_),
              AllOf(HasSubstr("plate.h5: /portrait/q_u: missing dataset"), HasSubstr("2-D float32")));
}

// Packages written before the run rules have no /palette/group or
// /palette/max_in_a_row: they load with every entry its own group, no limit.
TEST_F(PackageFileRejection, PackagesWithoutRunRulesLoadWithoutLimits) {
  remove("/palette/group");
  remove("/palette/max_in_a_row");
  const auto p = core::read_package(path_);
  EXPECT_EQ(p.palette.group, (std::vector<std::int32_t>{0, 1, 2}));
  EXPECT_EQ(p.palette.max_in_a_row, (std::vector<std::int32_t>{0, 0, 0}));
}

TEST_F(PackageFileRejection, WrongDtype) {
  replace<std::int32_t>("/mesh/triangles", std::vector<std::int32_t>(6, 0), {2, 3});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("/mesh/triangles: expected a 2-D uint32 dataset, got 2x3 int32"));
}

TEST_F(PackageFileRejection, WrongRank) {
  replace<float>("/portrait/qdot_u", std::vector<float>(10, 0.0f), {10});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("/portrait/qdot_u: expected a 2-D float32 dataset, got 10 float32"));
}

TEST_F(PackageFileRejection, InconsistentRank) {
  const auto p = testing::make_plate_package();
  const auto N = static_cast<std::uint64_t>(p.portrait.nodes());
  replace<float>("/portrait/qdot_u", std::vector<float>(N * 3, 0.0f), {N, 3});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr(fmt::format("/portrait/qdot_u: expected shape N x r_u = {}x4, got {}x3", N, N)));
}

TEST_F(PackageFileRejection, NotANumber) {
  const auto p = testing::make_plate_package();
  std::vector<float> q(p.portrait.q_u.data(), p.portrait.q_u.data() + p.portrait.q_u.size());
  q[17] = std::nanf("");
  replace<float>("/portrait/q_u", q, {static_cast<std::uint64_t>(p.portrait.q_u.rows()), 4});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("/portrait/q_u: expected finite values, got nan at flat index 17"));
}

TEST_F(PackageFileRejection, TriangleIndexOutOfRange) {
  replace<std::uint32_t>("/mesh/triangles", {0, 1, 9999}, {1, 3});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("/mesh/triangles: expected point indices in [0, 85), got 9999 at flat index 2"));
}

TEST_F(PackageFileRejection, UnknownFormatVersion) {
  core::h5::File::open_write(path_).write_attribute("format_version", std::int32_t{3});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("/@format_version: unknown format_version 3 (this build reads 1 to 2)"));
}

TEST_F(PackageFileRejection, AnotherPhasecastFileIsNamed) {
  core::h5::File::open_write(path_).write_attribute("format", std::string("phasecast-orbits"));
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("/@format: a 'phasecast-orbits' file, not a scene package (expected the output of "
                        "phasecast-precompute run or reduce)"));
}

TEST_F(PackageFileRejection, MissingAttribute) {
  core::h5::File::open_write(path_).remove_attribute("dt");
  EXPECT_THAT(package_rejection(path_), HasSubstr("/@dt: missing root attribute"));
}

TEST_F(PackageFileRejection, KinematicsColumns) {
  replace<float>("/palette/kinematics", std::vector<float>(9, 0.0f), {3, 3});
  EXPECT_THAT(
      package_rejection(path_),
      HasSubstr("/palette/kinematics: expected shape D x 11 (axis_x, ..., pulse_tau) = 3x11, got 3x3"));
}

// The optional appearance datasets' lengths are checked before anything is read.
TEST_F(PackageFileRejection, OptionalAppearanceFiguresOfTheWrongLength) {
  core::h5::File::open_write(path_).write("/appearance/transfer_sampling",
                                          std::vector<std::int32_t>{1024, 2, 7}.data(), {3});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("/appearance/transfer_sampling: expected length 2 (rays, bounces) = 2, got 3"));
  remove("/appearance/transfer_sampling");
  const auto figure = [this](const std::string& name, const std::vector<float>& values) {
    core::h5::File::open_write(path_).write("/appearance/held_out/" + name, values);
  };
  figure("l2_total_spread", {0.1f, 0.1f, 0.1f});
  EXPECT_THAT(
      package_rejection(path_),
      HasSubstr("/appearance/held_out/nodes: expected the nodes of the held-out figures beside them"));
  core::h5::File::open_write(path_).write("/appearance/held_out/nodes", std::vector<std::int32_t>{1, 2});
  EXPECT_THAT(package_rejection(path_), HasSubstr("/appearance/held_out/total: missing dataset"));
  for (const char* name : {"total", "truncation", "interpolation", "of_transfer"}) figure(name, {0.1f});
  EXPECT_THAT(package_rejection(path_), HasSubstr("/appearance/held_out/l2_total_spread: expected length 2 "
                                                  "(10th and 90th percentile) = 2, got 3"));
  remove("/appearance/held_out/l2_total_spread");
  figure("l2_floor", {0.1f, 0.2f});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("/appearance/held_out/l2_floor: expected length 1 (a figure) = 1, got 2"));
}

// Read before the name: a length that fits no interpolant.
TEST_F(PackageFileRejection, InterpolantParametersOfNoInterpolantsLength) {
  const auto p = core::read_package(path_);
  const auto affine = 1 + (1 + p.reduction.U_u.cols()) * p.appearance->U_a.cols();
  ASSERT_NE(affine, 3) << "3 values would fit affine-knn";
  remove("/appearance/interpolant_parameters");
  core::h5::File::open_write(path_).write("/appearance/interpolant_parameters",
                                          std::vector<float>(3, 0.5f).data(), {3});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr(fmt::format("/appearance/interpolant_parameters: expected at most 2 values, or {} "
                                    "(affine-knn, affine-knn-slope: k and a (1 + r_u) x r_a map), got 3",
                                    affine)));
}

TEST_F(PackageFileRejection, AppearanceBasisRows) {
  const auto r_a = static_cast<std::uint64_t>(testing::make_plate_package().rank_a());
  replace<float>("/appearance/U_a", std::vector<float>(4 * r_a, 0.0f), {4, r_a});
  EXPECT_THAT(package_rejection(path_), HasSubstr("/appearance/U_a: expected shape 48S x r_a"));
}

// ---- in-memory rules, shared by reader and writer ---------------------------------

std::string invalid(const core::ScenePackage& p) {
  try {
    core::validate_package(p, "pkg");
  } catch (const core::PackageError& e) {
    return e.what();
  }
  return "";
}

class PackageRule : public ::testing::Test {
 protected:
  core::ScenePackage p = testing::make_plate_package();
};

TEST_F(PackageRule, NearestIrfMustHaveTheRightPaletteEntry) {
  p.portrait.nearest_irf(3, 0) = p.portrait.irf_count() - 1;  // an IRF of entry 2
  EXPECT_THAT(invalid(p),
              HasSubstr("pkg: /portrait/nearest_irf: expected at [3, 0] -1 or an IRF of palette entry 0"));
}

TEST_F(PackageRule, IrfMustLieInsideThePortrait) {
  p.portrait.irf_length.back() += 1;
  EXPECT_THAT(invalid(p), HasSubstr("/portrait/irf_length: expected IRF 5"));
}

TEST_F(PackageRule, IrfPaletteIndexInRange) {
  p.portrait.irf_palette[1] = 3;
  EXPECT_THAT(invalid(p), HasSubstr("/portrait/irf_palette: expected palette indices in [0, 3), got 3"));
}

TEST_F(PackageRule, OnEndIsRestHoldOrAnEntry) {
  p.palette.on_end[0] = 5;
  EXPECT_THAT(
      invalid(p),
      HasSubstr("/palette/on_end: expected -2 (hold), -1 (rest) or an entry index in [-2, 3), got 5"));
}

TEST_F(PackageRule, GroupIsAnEntryAndRunLimitsAreCounts) {
  p.palette.group[1] = 3;
  EXPECT_THAT(invalid(p), HasSubstr("/palette/group: expected an entry index in [0, 3), got 3"));
  p.palette.group[1] = 1;
  p.palette.max_in_a_row[2] = -1;
  EXPECT_THAT(invalid(p), HasSubstr("/palette/max_in_a_row: expected a count in [0, 1000000), got -1"));
}

TEST_F(PackageRule, PaletteNamesUnique) {
  p.palette.names[2] = "close";
  EXPECT_THAT(invalid(p), HasSubstr("/palette/names: expected unique names, got 'close' twice"));
}

TEST_F(PackageRule, TransitionsShape) {
  p.palette.transitions.conservativeResize(3, 3);
  EXPECT_THAT(invalid(p), HasSubstr("/palette/transitions: expected shape (D+1) x D = 4x3, got 3x3"));
}

TEST_F(PackageRule, StaticPointsHaveZeroBasisRows) {
  const int board = p.mesh.points() - 1;  // a door-board corner
  p.reduction.U_u(3 * board, 0) = 0.5f;
  EXPECT_THAT(invalid(p), HasSubstr("/reduction/U_u: expected zero rows for static points"));
}

TEST_F(PackageRule, UnitKinematicsAxis) {
  p.palette.kinematics[1].axis = {0, 2, 0};
  EXPECT_THAT(invalid(p), HasSubstr("/palette/kinematics[1]: expected a unit axis, got length 2"));
}

TEST_F(PackageRule, PositiveTimeStep) {
  p.attributes.dt = 0;
  EXPECT_THAT(invalid(p), HasSubstr("/@dt: expected a positive time step"));
}

TEST_F(PackageRule, PositiveBlendRate) {
  p.attributes.blend_lambda = -1;
  EXPECT_THAT(invalid(p), HasSubstr("/@blend_lambda: expected lambda > 0"));
}

TEST_F(PackageRule, ClusterNodesInRange) {
  p.appearance->cluster_nodes[0] = p.portrait.nodes();
  EXPECT_THAT(invalid(p), HasSubstr("/appearance/cluster_nodes: expected state nodes"));
}

TEST_F(PackageRule, NrbfWidthsPositive) {
  p.appearance->nrbf_widths[2] = 0;
  EXPECT_THAT(invalid(p), HasSubstr("/appearance/nrbf_widths: expected positive finite widths, got 0 at 2"));
}

TEST_F(PackageRule, TransferWeightingIsEqualOrClusterSize) {
  for (const char* weighting : {"equal", "cluster size"}) {
    p.appearance->transfer_weighting = weighting;
    EXPECT_EQ(invalid(p), "") << weighting;
  }
  p.appearance->transfer_weighting = "cluster-size";
  EXPECT_THAT(invalid(p), HasSubstr("/appearance/transfer_weighting: expected \"equal\" or \"cluster size\", "
                                    "got \"cluster-size\""));
}

// nrbf and knn keep at most 2 parameters, affine-knn (and affine-knn-slope)
// its k and its (1 + r_u) x r_a affine map, which nothing else can be
// mistaken for.
TEST_F(PackageRule, InterpolantParametersFitTheInterpolant) {
  auto& a = *p.appearance;
  const Eigen::Index affine = 1 + (1 + a.nrbf_centers.cols()) * a.U_a.cols();
  ASSERT_GT(affine, 2);
  a.interpolant = "knn";
  a.interpolant_parameters = VectorXf::Constant(1, 3);
  EXPECT_EQ(invalid(p), "");
  a.interpolant = "affine-knn";
  EXPECT_THAT(invalid(p),
              HasSubstr(fmt::format("/appearance/interpolant_parameters: expected {} (k and a "
                                    "(1 + r_u) x r_a map) for interpolant \"affine-knn\", got 1 values",
                                    affine)));
  a.interpolant_parameters = VectorXf::Constant(affine, 0.5f);
  a.interpolant_parameters[0] = 2;
  EXPECT_EQ(invalid(p), "");
  a.interpolant = "affine-knn-slope";  // the same layout, neighbours in the map's image
  EXPECT_EQ(invalid(p), "");
  // k counts centres: a whole number in 1..N_a.
  const auto N_a = a.nrbf_centers.rows();
  for (const float k : {0.0f, 2.5f, static_cast<float>(N_a + 1)}) {
    a.interpolant_parameters[0] = k;
    EXPECT_THAT(invalid(p), HasSubstr(fmt::format("/appearance/interpolant_parameters: expected k (the first "
                                                  "value) a whole number in 1..{} (N_a), got {}",
                                                  N_a, k)));
  }
  a.interpolant_parameters[0] = static_cast<float>(N_a);
  EXPECT_EQ(invalid(p), "");
  a.interpolant = "knn";  // knn's k alike, NaN included
  for (const float k : {0.0f, -1.0f, std::nanf("")}) {
    a.interpolant_parameters = VectorXf::Constant(1, k);
    EXPECT_THAT(invalid(p), HasSubstr("/appearance/interpolant_parameters: expected k (the first value) a "
                                      "whole number in 1.."))
        << k;
  }
  a.interpolant_parameters = VectorXf::Constant(affine, 0.5f);
  a.interpolant = "nrbf";
  EXPECT_THAT(invalid(p), HasSubstr(fmt::format("/appearance/interpolant_parameters: expected at most 2 for "
                                                "interpolant \"nrbf\", got {} values",
                                                affine)));
  a.interpolant = "spline";
  EXPECT_THAT(invalid(p), HasSubstr("/appearance/interpolant: expected \"nrbf\", \"knn\", \"affine-knn\" or "
                                    "\"affine-knn-slope\", got \"spline\""));
}

// Every figure finite and >= 0, each 10th percentile at most its 90th.
TEST_F(PackageRule, HeldOutFiguresAreFiniteErrorsAndOrderedPercentiles) {
  core::HeldOutFigures& h = p.appearance->held_out.emplace();
  h.nodes = {1, 2};
  h.total = h.truncation = h.interpolation = h.of_transfer = 0.1f;
  EXPECT_EQ(invalid(p), "");  // the four plain figures alone
  h.l2_total_spread = core::Percentiles{0.1f, 0.2f};
  h.l2_of_variation_spread = core::Percentiles{0.2f, 0.3f};
  EXPECT_EQ(invalid(p), "");
  h.l2_of_variation_spread = core::Percentiles{0.4f, 0.3f};
  EXPECT_THAT(invalid(p),
              HasSubstr("/appearance/held_out/l2_of_variation_spread: expected the 10th percentile "
                        "<= the 90th"));
  h.l2_of_variation_spread.reset();
  h.l2_total_spread->p10 = std::nanf("");
  EXPECT_THAT(invalid(p),
              HasSubstr("/appearance/held_out/l2_total_spread: expected a finite error >= 0, got nan"));
  h.l2_total_spread.reset();
  h.interpolation = -0.1f;
  EXPECT_THAT(invalid(p),
              HasSubstr("/appearance/held_out/interpolation: expected a finite error >= 0, got -0.1"));
  h.interpolation = 0.1f;
  h.l2_floor = std::numeric_limits<float>::infinity();
  EXPECT_THAT(invalid(p), HasSubstr("/appearance/held_out/l2_floor: expected a finite error >= 0, got inf"));
  h.l2_floor.reset();
  h.nodes = {1, 999999};
  EXPECT_THAT(invalid(p), HasSubstr("/appearance/held_out/nodes: expected state nodes in [0, "));
}

// Fig. 12 out of sample: relative errors that never rise with the rank, at
// least r_a and at most N_a - 1 of them, agreeing at r_a with the l2
// truncation.
TEST_F(PackageRule, HeldOutTruncationCurveFallsAndMeetsTheTruncationAtRa) {
  auto& a = *p.appearance;
  const int r_a = a.rank(), K = a.clusters() - 1;
  ASSERT_GE(r_a, 1);
  ASSERT_GT(K, r_a);
  core::HeldOutFigures& h = a.held_out.emplace();
  h.nodes = {1, 2};
  h.total = h.truncation = h.interpolation = h.of_transfer = 0.1f;
  h.l2_truncation = 0.3f;
  VectorXf& curve = h.truncation_curve;
  curve = VectorXf::LinSpaced(K, 0.3f, 0.01f);
  curve[r_a - 1] = 0.3f;
  curve.head(r_a - 1).setConstant(0.4f);
  EXPECT_EQ(invalid(p), "");
  curve[r_a - 1] = 0.32f;
  EXPECT_THAT(invalid(p),
              HasSubstr(fmt::format("/appearance/held_out/truncation_curve: expected 0.3 at r_a = "
                                    "{} (the held-out l2_truncation), got 0.32",
                                    r_a)));
  curve[r_a - 1] = 0.3f;
  curve[K - 1] = 0.2f;
  EXPECT_THAT(invalid(p),
              HasSubstr(fmt::format("/appearance/held_out/truncation_curve: expected no rise with the rank, "
                                    "got 0.2 at rank {}",
                                    K)));
  curve[K - 1] = std::nanf("");
  EXPECT_THAT(invalid(p), HasSubstr(fmt::format("/appearance/held_out/truncation_curve: expected relative "
                                                "errors in [0, 1], got nan at rank {}",
                                                K)));
  curve[K - 1] = 0.0f;
  std::vector<Eigen::Index> lengths{K + 1};  // beyond what N_a centred fields resolve
  if (r_a > 1) lengths.push_back(r_a - 1);   // short of r_a (none stored is no curve)
  for (const Eigen::Index length : lengths) {
    VectorXf other = VectorXf::Zero(length);
    std::swap(other, curve);
    EXPECT_THAT(invalid(p),
                HasSubstr(fmt::format("/appearance/held_out/truncation_curve: expected at least r_a = {} and "
                                      "at most N_a - 1 = {} values, got {}",
                                      std::max(r_a, 1), K, length)));
    std::swap(other, curve);
  }
}

TEST_F(PackageRule, TransferSamplingIsRaysAndBouncesOrUnrecorded) {
  for (auto [rays, bounces] : {std::pair{1024, 2}, std::pair{64, 0}, std::pair{0, 0}}) {
    p.appearance->transfer_rays = rays;
    p.appearance->transfer_bounces = bounces;
    EXPECT_EQ(invalid(p), "") << rays << " " << bounces;
  }
  for (auto [rays, bounces] : {std::pair{-1, 0}, std::pair{64, -2}, std::pair{0, 2}}) {
    p.appearance->transfer_rays = rays;
    p.appearance->transfer_bounces = bounces;
    EXPECT_THAT(invalid(p), HasSubstr(fmt::format("/appearance/transfer_sampling: expected rays >= 1 and "
                                                  "bounces >= 0, got {} and {}",
                                                  rays, bounces)));
  }
}

TEST_F(PackageRule, AppearanceCoordinatesMatchRank) {
  p.portrait.q_a.conservativeResize(Eigen::NoChange, p.portrait.q_a.cols() + 1);
  EXPECT_THAT(invalid(p), HasSubstr("/portrait/q_a: expected shape N x r_a"));
}

TEST_F(PackageRule, NamesFromTheFileKeepMessagesOnOneLine) {
  p.palette.names = {"a\nb", "a\nb", "open"};
  EXPECT_THAT(invalid(p),
              AllOf(HasSubstr("expected unique names, got 'a\\x0ab' twice"), Not(HasSubstr("\n"))));
}

TEST_F(PackageRule, MessagesAreOneLine) {
  p.palette.on_end[0] = 5;
  EXPECT_THAT(invalid(p), Not(HasSubstr("\n")));
}

}  // namespace
}  // namespace phasecast
