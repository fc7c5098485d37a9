// phasecast-precompute simulate as a user runs it.

#include "phasecast/precompute/sampling/orbit_store.h"
#include "phasecast/precompute/simulation/obj_mesh.h"
#include "phasecast/precompute/simulation/scene.h"
#include "phasecast/precompute/simulation/self_collision.h"
#include "run_tool.h"
#include "source_tree.h"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <fmt/format.h>

#include <fstream>

namespace phasecast::precompute {
namespace {

const std::filesystem::path kScenes = phasecast::testing::scenes_dir();
using testing::run_tool;

TEST(SimulateCli, WritesOrbitStoreAndObjFrames) {
  const auto dir = testing::scratch_dir("cli_simulate");
  const auto r =
      run_tool("phasecast-precompute", {"simulate", (kScenes / "tiny/cloth_door.toml").string(), "--schedule",
                                        "open 0.5; stop 0.3; close 0.4", "-o", (dir / "run.h5").string(),
                                        "--obj-dir", (dir / "frames").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("simulate: 60/60 (100%)"), std::string::npos) << r.err;  // progress on a non-TTY
  const OrbitStore s = read_orbit_store(dir / "run.h5");
  EXPECT_EQ(s.frames(), 25 + 15 + 20);
  EXPECT_EQ(s.irf_palette, (std::vector<std::int32_t>{2, 1, 0}));
  const ObjMesh last = read_obj(dir / "frames/frame_00059.obj");
  EXPECT_EQ(last.vertices.rows(), s.vertices() + 8);  // cloth + door board
  EXPECT_FALSE(std::filesystem::exists(dir / "frames/frame_00060.obj"));
  // The self-contact line, its counts against a second read of the store.
  const Eigen::MatrixXi triangles = s.triangles.cast<int>();
  int intersecting = 0;
  for (int f = 0; f < s.frames(); ++f)
    intersecting += count_intersecting_pairs(s.positions.row(f).cast<double>().transpose(), triangles) > 0;
  EXPECT_NE(
      r.out.find(fmt::format("contact: {} of 60 frames with intersecting triangle pairs", intersecting)),
      std::string::npos)
      << r.out;
}

// The store names the scene file that made it, and phasecast-inspect
// summarises it (an orbit store, not a package) instead of refusing it.
TEST(SimulateCli, InspectSummarisesTheOrbitStore) {
  const auto dir = testing::scratch_dir("cli_simulate_inspect");
  const auto scene = kScenes / "tiny/cloth_door.toml";
  ASSERT_EQ(run_tool("phasecast-precompute", {"simulate", scene.string(), "--schedule", "open 0.5; stop 0.3",
                                              "-o", (dir / "run.h5").string()})
                .exit_code,
            0);
  EXPECT_EQ(read_orbit_store(dir / "run.h5").scene_file, std::filesystem::absolute(scene).lexically_normal());
  const auto text = run_tool("phasecast-inspect", {(dir / "run.h5").string()});
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("an orbit store (not a package"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("40 frames (0.80 s at dt 0.02 s) in 2 IRFs"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("see it: phasecast-render --simulation"), std::string::npos) << text.out;
  const auto json = run_tool("phasecast-inspect", {(dir / "run.h5").string(), "--json"});
  ASSERT_EQ(json.exit_code, 0) << json.err;
  EXPECT_NE(json.out.find("\"kind\": \"orbit store\""), std::string::npos) << json.out;
  EXPECT_NE(json.out.find("\"open\": 1"), std::string::npos) << json.out;
}

// The least det F of a solid's tets, against a second reader: signed volumes
// from triple products of the stored positions over those of the rest shape.
TEST(SimulateCli, ReportsHowFarTheSolidsTetsWereSquashed) {
  const auto dir = testing::scratch_dir("cli_simulate_tets");
  const auto scene_path = kScenes / "tiny/toy_dashboard.toml";
  const auto r = run_tool("phasecast-precompute", {"simulate", scene_path.string(), "--schedule",
                                                   "forward 0.3; back 0.3", "-o", (dir / "run.h5").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Scene scene = load_scene_file(scene_path);
  const OrbitStore s = read_orbit_store(dir / "run.h5");
  ASSERT_EQ(s.vertices(), scene.model.vertices());
  const auto volume6 = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                          const Eigen::Vector3d& d) { return (b - a).cross(c - a).dot(d - a); };
  double least = 1e9;
  int inverted_frames = 0;
  for (int f = 0; f < s.frames(); ++f) {
    bool inverted = false;
    for (const auto& t : scene.model.tets) {
      const auto x = [&](int k) {
        return Eigen::Vector3d(s.positions.row(f).segment<3>(3 * t.v[k]).cast<double>());
      };
      const auto X = [&](int k) { return Eigen::Vector3d(scene.model.rest.segment<3>(3 * t.v[k])); };
      const double J = volume6(x(0), x(1), x(2), x(3)) / volume6(X(0), X(1), X(2), X(3));
      least = std::min(least, J);
      inverted = inverted || J <= 0;
    }
    inverted_frames += inverted;
  }
  EXPECT_LT(least, 0.99);  // not vacuous: the jolts squash the glued base
  const auto at = r.out.find("tetrahedra: least J = det F ");
  ASSERT_NE(at, std::string::npos) << r.out;
  EXPECT_NEAR(std::stod(r.out.substr(at + 28)), least, 1e-3) << r.out;
  EXPECT_NE(
      r.out.find(fmt::format("{} of {} frames with an inverted tet (J <= 0)", inverted_frames, s.frames())),
      std::string::npos)
      << r.out;
}

TEST(SimulateCli, HelpListsTheSubcommand) {
  const auto r = run_tool("phasecast-precompute", {"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("simulate"), std::string::npos);
}

void expect_one_line_failure(const testing::ToolResult& r, const std::string& fragment) {
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err.rfind("phasecast-precompute: ", 0), 0u) << r.err;
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "one line: " << r.err;
  EXPECT_NE(r.err.find(fragment), std::string::npos) << r.err;
}

TEST(SimulateCli, MissingSceneFails) {
  const auto dir = testing::scratch_dir("simulate_cli_missing");
  expect_one_line_failure(run_tool("phasecast-precompute", {"simulate", "/no/scene.toml", "--schedule",
                                                            "open 1", "-o", (dir / "x.h5").string()}),
                          "/no/scene.toml");
  EXPECT_FALSE(std::filesystem::exists(dir / "x.h5"));
}

TEST(SimulateCli, UnknownPaletteEntryFails) {
  const auto dir = testing::scratch_dir("cli_unknown");
  expect_one_line_failure(
      run_tool("phasecast-precompute", {"simulate", (kScenes / "tiny/cloth_door.toml").string(), "--schedule",
                                        "slam 1", "-o", (dir / "x.h5").string()}),
      "unknown palette entry 'slam' (expected one of: close, stop, open)");
}

}  // namespace
}  // namespace phasecast::precompute
