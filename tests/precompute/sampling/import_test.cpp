// phasecast-precompute import on a small OBJ-sequence fixture: a square sheet
// translating at a known speed (open) and then at rest (stop).

#include "error_of.h"
#include "phasecast/precompute/sampling/orbit_import.h"
#include "phasecast/precompute/simulation/obj_mesh.h"
#include "run_tool.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <fstream>

namespace phasecast::precompute {
namespace {

using phasecast::testing::error_of;

const char* kManifest = R"(scene = "external_sheet"
dt = 0.1
pinned = [0]

[[palette]]
name = "open"
alpha_impulse = [0, 1, 0]
alpha_forcing = [0, 1, 0]
kinematics = { motion = "rotational", axis = [0, 1, 0], rate = 1, range = [0, 1.5708] }

[[palette]]
name = "stop"
alpha_impulse = [0, 0, 0]
alpha_forcing = [0, 0, 0]

[[irf]]
palette = "open"
frames = "open_0"

[[irf]]
palette = "stop"
frames = "stop_0"
)";

Eigen::MatrixX3i square_triangles() {
  Eigen::MatrixX3i f(2, 3);
  f << 0, 1, 2, 0, 2, 3;
  return f;
}

// Frame k of the "open" IRF: the square moved by 0.02 k along x.
Eigen::MatrixX3d square(double dx) {
  Eigen::MatrixX3d v(4, 3);
  v << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
  v.col(0).array() += dx;
  return v;
}

std::filesystem::path make_fixture(const std::string& name, const std::string& manifest = kManifest) {
  const auto dir = testing::scratch_dir(name);
  std::filesystem::create_directories(dir / "open_0");
  std::filesystem::create_directories(dir / "stop_0");
  for (int k = 0; k < 4; ++k)
    write_obj(dir / "open_0" / ("f" + std::to_string(k) + ".obj"), square(0.02 * k), square_triangles());
  for (int k = 0; k < 2; ++k)
    write_obj(dir / "stop_0" / ("f" + std::to_string(k) + ".obj"), square(0.06), square_triangles());
  std::ofstream(dir / "manifest.toml") << manifest;
  return dir / "manifest.toml";
}

TEST(Import, ObjSequencesBecomeAnOrbitStore) {
  const OrbitStore s = import_orbits(make_fixture("import_ok"));
  EXPECT_EQ(s.scene, "external_sheet");
  EXPECT_EQ(s.source, "import");
  ASSERT_EQ(s.frames(), 6);
  EXPECT_EQ(s.vertices(), 4);
  EXPECT_EQ(s.irf_start, (std::vector<std::int32_t>{0, 4}));
  EXPECT_EQ(s.irf_palette, (std::vector<std::int32_t>{0, 1}));
  EXPECT_EQ(s.pinned, (std::vector<std::uint8_t>{1, 0, 0, 0}));
  EXPECT_FLOAT_EQ(s.positions(3, 0), 0.06f);
  // Eq. 8: 0.02 m per 0.1 s along x in "open"; its first frame starts from rest (the
  // manifest does not say it continues anything), so it has no pre-impulse velocity.
  EXPECT_EQ(s.irf_continues, (std::vector<std::uint8_t>{0, 0}));
  EXPECT_NEAR(s.velocities(0, 0), 0.0f, 1e-6);
  for (int f = 1; f < 4; ++f) EXPECT_NEAR(s.velocities(f, 0), 0.2f, 1e-5) << f;
  EXPECT_NEAR(s.velocities(4, 0), 0.0f, 1e-6);
  EXPECT_NEAR(s.velocities(5, 0), 0.0f, 1e-6);
  EXPECT_TRUE(s.kinematics[0].rotational);
  EXPECT_FLOAT_EQ(s.kinematics[0].range_max, 1.5708f);
  EXPECT_FLOAT_EQ(s.support(2, 0), 1.0f);
}

TEST(Import, CliWritesTheStore) {
  const auto manifest = make_fixture("import_cli");
  const auto out = manifest.parent_path() / "orbits.h5";
  const auto r = testing::run_tool("phasecast-precompute", {"import", manifest.string(), "-o", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_orbit_store(out).frames(), 6);
}

// A scene file of the imported sheet: a membrane with the given mesh line and
// the manifest's palette names and frame spacing.
std::string sheet_scene(const std::string& name, const std::string& mesh) {
  return "name = \"" + name + R"("
[simulation]
frame_dt = 0.1
[support]
motion = "rotational"
axis = [0, 1, 0]
range = [0, 90]
[[body]]
name = "sheet"
energies = ["membrane"]
density = 0.2
young = 100
)" + mesh +
         R"(
pin = { min = [-0.01, -0.01, -0.01], max = [0.01, 0.01, 0.01] }
[[palette]]
name = "open"
alpha_impulse = [0, 1, 0]
alpha_forcing = [0, 1, 0]
[[palette]]
name = "stop"
alpha_impulse = [0, 0, 0]
alpha_forcing = [0, 0, 0]
)";
}

// The route for another simulator's orbits (README, docs/simulator.md): import, then
// reduce with a scene file that describes the same mesh, palette names and frame
// spacing (its physics is not used: nothing is simulated).
TEST(Import, ImportedOrbitsReduceIntoAServablePackage) {
  const auto manifest = make_fixture("import_reduce");
  const auto dir = manifest.parent_path();
  std::ofstream(dir / "sheet.toml") << sheet_scene("external_sheet", R"(obj = { path = "open_0/f0.obj" })");
  const auto orbits = (dir / "orbits.h5").string(), package = (dir / "sheet.h5").string();
  auto r = testing::run_tool("phasecast-precompute", {"import", manifest.string(), "-o", orbits});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = testing::run_tool("phasecast-precompute",
                        {"reduce", (dir / "sheet.toml").string(), orbits, "-o", package, "--clusters", "4"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = testing::run_tool("phasecast-inspect", {package});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("n_irf = 2 IRFs"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("0: open (1 IRFs), 1: stop (1 IRFs)"), std::string::npos) << r.out;

  // A scene file of another mesh is refused with what does not match.
  std::ofstream(dir / "other.toml") << sheet_scene(
      "other", "grid = { origin = [0, 0, 0], u = [1, 0, 0], v = [0, 1, 0], cells = [2, 2] }");
  r = testing::run_tool("phasecast-precompute",
                        {"reduce", (dir / "other.toml").string(), orbits, "-o", package});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("does not belong to scene 'other': 4 vertices in the store, 9 in the scene"),
            std::string::npos)
      << r.err;

  // The manifest's range is the scene's: a scene whose door stops at 45 degrees is refused, naming both.
  std::string narrow = sheet_scene("external_sheet", R"(obj = { path = "open_0/f0.obj" })");
  narrow.replace(narrow.find("range = [0, 90]"), 15, "range = [0, 45]");
  std::ofstream(dir / "narrow.toml") << narrow;
  r = testing::run_tool("phasecast-precompute",
                        {"reduce", (dir / "narrow.toml").string(), orbits, "-o", package});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(
      r.err.find("'open' has the range [0, 1.5708] in the store, [0, 0.7853982] in the scene's [support]"),
      std::string::npos)
      << r.err;
}

// The other tool moved the support: frame k turned the sheet by 0.1 (k + 1) rad
// about y and shifted it, written in world coordinates with the motion in
// open_0/support.txt (the first frame, the rest mesh, is not the identity).
std::filesystem::path make_turning_fixture(const std::string& name, const std::string& extra_line = "") {
  std::string manifest = kManifest;
  manifest.replace(manifest.find("pinned = [0]"), 12, "pinned = [0]\npositions = \"world\"");
  manifest.replace(manifest.find("frames = \"open_0\""), 17,
                   "frames = \"open_0\"\nsupport = \"open_0/support.txt\"");
  const auto path = make_fixture(name, manifest);
  std::ofstream support(path.parent_path() / "open_0" / "support.txt");
  support << "# [R | t] of the support, one frame a line\n";
  for (int k = 0; k < 4; ++k) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.1 * (k + 1), Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Vector3d t(0.5 * (k + 1), 0, 0);
    write_obj(path.parent_path() / "open_0" / ("f" + std::to_string(k) + ".obj"),
              ((square(0) * R.transpose()).rowwise() + t.transpose()).eval(), square_triangles());
    for (int r = 0; r < 3; ++r) support << R(r, 0) << ' ' << R(r, 1) << ' ' << R(r, 2) << ' ' << t(r) << ' ';
    support << '\n';
  }
  support << extra_line;
  return path;
}

TEST(Import, SupportTransformsPerFrameMoveTheSupport) {
  const OrbitStore s = import_orbits(make_turning_fixture("import_support"));
  ASSERT_EQ(s.frames(), 6);
  for (int f = 0; f < 4; ++f) {
    // In the support's frame the sheet never moved; the store keeps the turn.
    for (int c = 0; c < 12; ++c) EXPECT_NEAR(s.positions(f, c), square(0)(c / 3, c % 3), 1e-5) << f;
    EXPECT_NEAR(s.support(f, 0), std::cos(0.1 * (f + 1)), 1e-6);
    EXPECT_NEAR(s.support(f, 2), std::sin(0.1 * (f + 1)), 1e-6);
    EXPECT_NEAR(s.support(f, 3), 0.5 * (f + 1), 1e-6);
  }
  for (int c = 0; c < 12; ++c) EXPECT_NEAR(s.rest_positions(c / 3, c % 3), square(0)(c / 3, c % 3), 1e-5);
  EXPECT_FLOAT_EQ(s.support(4, 0), 1.0f);  // stop_0 names no transforms: the identity
  EXPECT_FLOAT_EQ(s.support(4, 3), 0.0f);
  EXPECT_NEAR(s.velocities(2, 0), 0.0f, 1e-4);
}

TEST(ImportErrors, SupportTransformsMustMatchTheFramesAndBeRigid) {
  const auto extra = make_turning_fixture("import_support_count", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  const auto dir = extra.parent_path();
  EXPECT_EQ(error_of([&] { import_orbits(extra); }), (dir / "open_0/support.txt").string() +
                                                         ": 5 transforms for the 4 OBJ frames of " +
                                                         (dir / "open_0").string());
  const auto sheared = make_turning_fixture("import_support_shear");
  std::ofstream(sheared.parent_path() / "open_0/support.txt")
      << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0.5 0 0 0 1 0 0 0 0 1 0\n";
  EXPECT_EQ(error_of([&] { import_orbits(sheared); }),
            (sheared.parent_path() / "open_0/support.txt").string() +
                ":2: expected a rotation in the first 3 columns (a rigid support)");
}

TEST(ImportErrors, TopologyMismatch) {
  const auto manifest = make_fixture("import_topology");
  Eigen::MatrixX3i one(1, 3);
  one << 0, 1, 2;
  write_obj(manifest.parent_path() / "stop_0/f1.obj", square(0.06), one);
  EXPECT_EQ(error_of([&] { import_orbits(manifest); }),
            (manifest.parent_path() / "stop_0/f1.obj").string() + ": expected the topology of " +
                (manifest.parent_path() / "open_0/f0.obj").string() +
                " (4 vertices, 2 triangles), got 4 vertices, 1 triangles");
}

TEST(ImportErrors, UnknownPaletteName) {
  std::string text = kManifest;
  text.replace(text.find("palette = \"stop\""), 16, "palette = \"slam\"");
  const auto manifest = make_fixture("import_palette", text);
  EXPECT_EQ(error_of([&] { import_orbits(manifest); }),
            manifest.string() +
                ": field 'irf[1].palette': expected the name of a [[palette]] entry, got string \"slam\"");
}

TEST(ImportErrors, MissingFramesFolder) {
  std::string text = kManifest;
  text.replace(text.find("frames = \"stop_0\""), 17, "frames = \"nowhere\"");
  const auto manifest = make_fixture("import_folder", text);
  EXPECT_EQ(error_of([&] { import_orbits(manifest); }),
            manifest.string() +
                ": field 'irf[1].frames': expected a folder of OBJ frames (relative to the manifest), got "
                "string \"nowhere\"");
}

TEST(ImportErrors, CliReportsOneLine) {
  const auto r =
      testing::run_tool("phasecast-precompute", {"import", "/no/manifest.toml", "-o", "/tmp/x.h5"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err.rfind("phasecast-precompute: /no/manifest.toml", 0), 0u) << r.err;
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1);
}

}  // namespace
}  // namespace phasecast::precompute
