// phasecast-inspect as a user runs it: exit codes, one-line errors, JSON.

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/package.h"
#include "phasecast/core/package_summary.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>

namespace phasecast {
namespace {

using ::testing::HasSubstr;

class InspectCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("inspect_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    package_ = testing::make_plate_package();
    core::write_package(package_, dir_ / "plate.h5");
  }
  static int lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

  std::filesystem::path dir_;
  core::ScenePackage package_;
};

TEST_F(InspectCli, ValidPackageText) {
  const auto r = testing::run_tool("phasecast-inspect", {(dir_ / "plate.h5").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("scene        plate"));
  EXPECT_THAT(r.out, HasSubstr(fmt::format("S = {} scene points", package_.mesh.points())));
  EXPECT_THAT(r.out, HasSubstr(fmt::format("N = {} state nodes", package_.portrait.nodes())));
  EXPECT_THAT(r.out, HasSubstr("n_irf = 6 IRFs"));
  EXPECT_THAT(r.out, HasSubstr("D = 3: 0: close (2 IRFs), 1: stop (2 IRFs), 2: open (2 IRFs)"));
  EXPECT_THAT(r.out, HasSubstr("r_u = 4"));
  EXPECT_THAT(r.out, HasSubstr(fmt::format("r_a = {}", package_.rank_a())));
}

TEST_F(InspectCli, ValidPackageJson) {
  const auto r =
      testing::run_tool("phasecast-inspect", {(dir_ / "plate.h5").string(), "--json", "--rank", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["scene"], "plate");
  EXPECT_EQ(j["N"], package_.portrait.nodes());
  EXPECT_EQ(j["D"], 3);
  EXPECT_EQ(j["r_u"], 4);
  EXPECT_EQ(j["rank"], 2);
  EXPECT_NEAR(j["rel_error_u"].get<double>(), package_.reduction.rel_error[1], 1e-7);
  // The paper's relErr (§2.3.1) at rank 2 is sigma_3 / sigma_1 of the package's curve.
  const auto& sigma = package_.reduction.singular_values;
  EXPECT_NEAR(j["sigma_ratio_u"].get<double>(), sigma[2] / sigma[0], 1e-7);
  EXPECT_EQ(j["singular_values_u"].size(), static_cast<size_t>(sigma.size()));
  // The same figure for the appearance (Table 1's second relErr), at r_a.
  const auto& sigma_a = package_.appearance->singular_values;
  ASSERT_LT(package_.rank_a(), sigma_a.size());
  EXPECT_NEAR(j["sigma_ratio_a"].get<double>(), sigma_a[package_.rank_a()] / sigma_a[0], 1e-6);
  EXPECT_EQ(j["singular_values_a"].size(), static_cast<size_t>(sigma_a.size()));
  EXPECT_EQ(j["frame_state_bytes"], 4 * (4 + package_.rank_a() + 12));
  EXPECT_EQ(j["file_bytes"], std::filesystem::file_size(dir_ / "plate.h5"));
}

// A package without the weighting and the figures of the nodes' own
// variation (no /appearance/transfer_weighting) reads as equal weights, with
// those figures unknown rather than 0.
TEST_F(InspectCli, AbsentHeldOutFiguresReadAsEqualWeightsAndUnknownVariation) {
  core::HeldOutFigures& h = package_.appearance->held_out.emplace();
  h.nodes = {1, 2};
  h.total = 0.3f;
  h.truncation = 0.2f;
  h.interpolation = 0.1f;
  h.of_transfer = 0.01f;
  h.l2_total = 0.25f;
  h.l2_truncation = 0.2f;
  h.clusters_l2_truncation = 0.15f;
  h.l2_floor = 0.1f;
  h.l2_total_spread = core::Percentiles{0.2f, 0.3f};
  h.l2_truncation_spread = core::Percentiles{0.15f, 0.25f};
  const auto path = dir_ / "older.h5";
  core::write_package(package_, path);
  core::h5::File::open_write(path).remove("/appearance/transfer_weighting");
  EXPECT_EQ(core::read_package(path).appearance->transfer_weighting, "equal");
  const auto r = testing::run_tool("phasecast-inspect", {path.string(), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["transfer_weighting"], "equal");
  EXPECT_NEAR(j["held_out"]["l2_floor"].get<double>(), 0.1, 1e-7);
  EXPECT_TRUE(j["held_out"]["of_variation"].is_null());
  EXPECT_TRUE(j["held_out"]["l2_floor_of_variation"].is_null());
  const auto text = testing::run_tool("phasecast-inspect", {path.string()});
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_THAT(text.out, HasSubstr("transfer fields weighted equal"));
  EXPECT_THAT(text.out, ::testing::Not(HasSubstr("of the nodes' own variation")));
  EXPECT_THAT(text.out, HasSubstr("over resampled nodes (10th-90th percentile): 20-30%, truncation 15-25%"));
  EXPECT_THAT(text.out, ::testing::Not(HasSubstr("of their own variation over resampled nodes")));
  EXPECT_EQ(j["held_out"]["l2_spread"].size(), 4u);
}

// /fidelity/: written, read back and printed, with adaptive sampling's figures.
TEST_F(InspectCli, PlaybackFidelityIsStoredAndPrinted) {
  core::PlaybackFidelity& f = package_.fidelity.emplace();
  f.schedules = 20;
  f.items = 4;
  f.seed = 1952813667;
  f.median_nrmse = 0.056f;
  f.p90_nrmse = 0.206f;
  f.moving = 80;
  f.moving_within = 79;
  f.switches = 85;
  f.switches_within = 76;
  const auto path = dir_ / "fidelity.h5";
  core::write_package(package_, path);
  auto text = testing::run_tool("phasecast-inspect", {path.string()});
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_THAT(text.out,
              HasSubstr("fidelity     playback vs the full simulation over 20 random schedules of 4 "
                        "entries (seed 1952813667): median NRMSE 0.056, 90th percentile 0.206; 79 of 80 "
                        "moving segments within [0.67, 1.5] of the simulated motion, 76 of 85 switches"));
  EXPECT_THAT(text.out, ::testing::Not(HasSubstr("sampled adaptively")));
  f.target_median_nrmse = 0.1f;
  f.sampled_irfs = 24;
  f.rounds = 3;
  f.target_met = true;
  core::write_package(package_, path);
  const auto back = core::read_package(path).fidelity;
  ASSERT_TRUE(back && back->target_median_nrmse);
  EXPECT_EQ(back->seed, 1952813667.0);
  EXPECT_EQ(back->switches_within, 76);
  EXPECT_EQ(back->sampled_irfs, 24);
  EXPECT_TRUE(back->target_met);
  text = testing::run_tool("phasecast-inspect", {path.string()});
  EXPECT_THAT(text.out,
              HasSubstr("sampled adaptively towards median NRMSE 0.100: met after 24 IRFs in 3 rounds"));
  const auto j = nlohmann::json::parse(testing::run_tool("phasecast-inspect", {path.string(), "--json"}).out);
  EXPECT_EQ(j["fidelity"]["moving_segments_within"], 79);
  EXPECT_NEAR(j["fidelity"]["p90_nrmse"].get<double>(), 0.206, 1e-7);
  EXPECT_EQ(j["fidelity"]["adaptive"]["rounds"], 3);
  // Refused: a share that is no share, a 90th percentile below the median, half the adaptive figures.
  f.moving_within = 81;
  EXPECT_THROW(core::write_package(package_, path), core::PackageError);
  f.moving_within = 79;
  f.p90_nrmse = 0.05f;
  EXPECT_THROW(core::write_package(package_, path), core::PackageError);
  f.p90_nrmse = 0.206f;
  core::write_package(package_, path);
  core::h5::File::open_write(path).remove("/fidelity/rounds");
  EXPECT_THAT(testing::package_rejection(path), HasSubstr("/fidelity/rounds: missing dataset"));
  // A package without /fidelity says nothing of it (JSON: null).
  EXPECT_TRUE(
      nlohmann::json::parse(
          testing::run_tool("phasecast-inspect", {(dir_ / "plate.h5").string(), "--json"}).out)["fidelity"]
          .is_null());
}

// Fig. 12 out of sample, as stored: the text names r_a and the paper's r_a
// among the powers of two, the whole span, and the first rank that fits the
// held-out states as well as the clusters fit themselves at r_a.
TEST(HeldOutCurveText, NamesTheRanksAndWhereTheInSampleFigureIsReached) {
  const std::vector<double> curve{0.5, 0.3, 0.2, 0.12, 0.1, 0.08, 0.07, 0.06, 0.055, 0.05};
  const std::string ranks =
      "1: 50%, 2: 30%, r_a = 3: 20%, 4: 12%, the paper's r_a = 6: 8%, 8: 6%, all 10 directions of the "
      "clusters: 5%";
  EXPECT_EQ(core::held_out_curve_text(curve, 3, 6, 0.09),
            ranks + "; as low as the clusters' own truncation at r_a measured alike (9%) from rank 6");
  EXPECT_EQ(core::held_out_curve_text(curve, 3, 6, 0.01),
            ranks + "; never as low as the clusters' own truncation at r_a measured alike (1%)");
  EXPECT_EQ(core::held_out_curve_text(curve, 3, 6, std::nan("")), ranks);
  // r_a at the last rank keeps its name beside "all K".
  EXPECT_EQ(core::held_out_curve_text({0.4, 0.2}, 2, 0, 0.5),
            "1: 40%, r_a = 2: 20%, all 2 directions of the clusters: 20%; as low as the clusters' own "
            "truncation at r_a measured alike (50%) from rank 1");
  EXPECT_EQ(core::held_out_curve_text({}, 3, 6, 0.1), "");
}

TEST_F(InspectCli, HeldOutTruncationCurveIsPrintedAndInTheJson) {
  auto& a = *package_.appearance;
  const int r_a = a.rank(), K = a.clusters() - 1;
  core::HeldOutFigures& h = a.held_out.emplace();
  h.nodes = {1, 2};
  h.total = h.truncation = h.interpolation = h.of_transfer = 0.1f;
  h.l2_total = h.l2_floor = h.of_variation = h.l2_of_variation = h.l2_floor_of_variation = 0.1f;
  h.clusters_l2_truncation = 0.005f;  // the clusters' own truncation measured alike: below the whole curve
  h.truncation_curve = VectorXf::LinSpaced(K, 0.1f, 0.01f);
  h.l2_truncation = h.truncation_curve[r_a - 1];
  const auto path = dir_ / "curve.h5";
  core::write_package(package_, path);
  EXPECT_EQ(core::read_package(path).appearance->held_out->truncation_curve, h.truncation_curve);
  const auto j = nlohmann::json::parse(testing::run_tool("phasecast-inspect", {path.string(), "--json"}).out);
  ASSERT_EQ(j["held_out"]["l2_truncation_curve"].size(), static_cast<size_t>(K));
  EXPECT_NEAR(j["held_out"]["l2_truncation_curve"][0].get<double>(), 0.1, 1e-7);
  EXPECT_NEAR(j["held_out"]["l2_truncation_curve"][K - 1].get<double>(), 0.01, 1e-7);
  const auto text = testing::run_tool("phasecast-inspect", {path.string()});
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_THAT(text.out,
              HasSubstr("held-out truncation by rank (Fig. 12 out of sample, relative l2): 1: 10%, "));
  EXPECT_THAT(text.out, HasSubstr(fmt::format("all {} directions of the clusters: 1%; never as low as the "
                                              "clusters' own truncation at r_a measured alike (0.5%)",
                                              K)));
  // Without the curve (older packages) the line is left out, and the JSON says null.
  const auto plain = nlohmann::json::parse(
      testing::run_tool("phasecast-inspect", {(dir_ / "plate.h5").string(), "--json"}).out);
  EXPECT_THAT(testing::run_tool("phasecast-inspect", {(dir_ / "plate.h5").string()}).out,
              ::testing::Not(HasSubstr("held-out truncation by rank")));
  EXPECT_TRUE(plain["held_out"].is_null() || plain["held_out"]["l2_truncation_curve"].is_null());
}

TEST_F(InspectCli, TruncatedPackageFailsWithOneLine) {
  std::filesystem::resize_file(dir_ / "plate.h5", 4000);
  const auto r = testing::run_tool("phasecast-inspect", {(dir_ / "plate.h5").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr("phasecast-inspect: "));
  EXPECT_THAT(r.err, HasSubstr("plate.h5"));
  EXPECT_EQ(r.out, "");
}

TEST_F(InspectCli, CorruptedPackageFailsWithOneLine) {
  // Overwrite a block in the middle of the file (metadata and data alike are checksummed).
  const auto size = std::filesystem::file_size(dir_ / "plate.h5");
  std::fstream f(dir_ / "plate.h5", std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(static_cast<std::streamoff>(size / 2));
  const std::string junk(256, '\x5a');
  f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  f.close();
  const auto r = testing::run_tool("phasecast-inspect", {(dir_ / "plate.h5").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr("plate.h5"));
}

TEST_F(InspectCli, WrongShapedPackageFailsWithOneLine) {
  // Reshape a dataset with h5py, as a buggy third-party writer would.
  const std::string script = fmt::format(
      "import h5py, numpy as np\nf = h5py.File('{}', 'r+')\nq = f['/portrait/qdot_u'][:, :2]\n"
      "del f['/portrait/qdot_u']\nf['/portrait/qdot_u'] = q\nf.close()\n",
      (dir_ / "plate.h5").string());
  std::ofstream(dir_ / "reshape.py") << script;
  ASSERT_EQ(std::system(fmt::format("/usr/bin/python3 {}", (dir_ / "reshape.py").string()).c_str()), 0);
  const auto r = testing::run_tool("phasecast-inspect", {(dir_ / "plate.h5").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr("/portrait/qdot_u: expected shape N x r_u"));
}

TEST_F(InspectCli, NonHdf5FileFailsWithOneLine) {
  std::ofstream(dir_ / "notes.h5") << "hello";
  const auto r = testing::run_tool("phasecast-inspect", {(dir_ / "notes.h5").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, fmt::format("phasecast-inspect: {}: not an HDF5 file (or truncated)\n",
                               (dir_ / "notes.h5").string()));
}

TEST_F(InspectCli, HelpDescribesTheTool) {
  const auto r = testing::run_tool("phasecast-inspect", {"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("--json"));
}

}  // namespace
}  // namespace phasecast
