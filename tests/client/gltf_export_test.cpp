// phasecast-export as a user runs it: the files pass the Khronos glTF
// validator (npm, scripts/gltf-validate), tinygltf reads them back into eq. 7
// at a recorded frame, the instance is the one asked for, and bad inputs give
// one-line errors. The independent reader (h5py, struct) is
// check_gltf_export.py.

#include "phasecast/client/gltf_export.h"
#include "phasecast/client/client_basis.h"
#include "phasecast/client/sh_light.h"
#include "phasecast/core/hash.h"
#include "run_tool.h"
#include "source_tree.h"
#include "synthetic_package.h"
#include "test_peer.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>
#include <Eigen/Geometry>

#include <sys/wait.h>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <utility>

namespace phasecast::client {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

const std::filesystem::path kSourceDir = phasecast::testing::source_dir();
const std::filesystem::path kTestData = kSourceDir / "tests" / "data";
const std::filesystem::path kValidator = kSourceDir / "scripts" / "gltf-validate" / "validate.mjs";

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

CommandResult run_command(const std::string& command) {
  CommandResult r;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe)) r.output += buffer;
  const int status = ::pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128;
  return r;
}

class GltfExport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("gltf_export_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    package_ = testing::make_plate_package();
    write(package_, "plate.h5");
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::uint64_t write(const core::ScenePackage& p, const std::string& name) const {
    core::write_package(p, dir_ / name);
    return core::file_content_hash(dir_ / name);
  }
  // A recording of IRF `irf` of the plate, made with package file `file`.
  void record(const std::string& name, const std::string& file, int irf = 3) const {
    testing::write_recording(dir_ / name, "plate", file, core::file_content_hash(dir_ / file),
                             testing::irf_stream(package_, irf));
  }
  testing::ToolResult exported(const std::vector<std::string>& args) const {
    const auto r = testing::run_tool("phasecast-export", args);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r;
  }
  // Runs the tool and expects exit status `code`, exactly one line on stderr
  // and nothing left behind: no out.glb, no temporary *.partial-<pid> file.
  std::string one_line_error(const std::vector<std::string>& args, int code = 1) const {
    const auto r = testing::run_tool("phasecast-export", args);
    EXPECT_EQ(r.exit_code, code) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "out.glb"));
    for (const auto& entry : std::filesystem::recursive_directory_iterator(dir_)) {
      EXPECT_EQ(entry.path().filename().string().find(".partial-"), std::string::npos)
          << entry.path() << " left behind by: " << r.err;
    }
    return r.err;
  }
  tinygltf::Model load(const std::string& name) const {
    tinygltf::Model m;
    std::string err, warn;
    EXPECT_TRUE(tinygltf::TinyGLTF().LoadBinaryFromFile(&m, &err, &warn, path(name))) << err;
    return m;
  }

  std::filesystem::path dir_;
  core::ScenePackage package_;
};

// The plate with its door board fixed in the world: two meshes, one under the
// support node with morph targets, one at the root without.
core::ScenePackage plate_with_world_board() {
  auto p = testing::make_plate_package();
  const auto S = static_cast<std::size_t>(p.mesh.points());
  for (std::size_t v = S - 4; v < S; ++v) p.mesh.attached[v] = 0;
  return p;
}

// Nothing attached: the whole plate is one world mesh with the morph targets
// and there is no support node.
core::ScenePackage loose_plate() {
  auto p = testing::make_plate_package();
  std::fill(p.mesh.attached.begin(), p.mesh.attached.end(), 0);
  return p;
}

TEST_F(GltfExport, KhronosValidatorFindsNoIssues) {
  ASSERT_TRUE(std::filesystem::exists(kValidator.parent_path() / "node_modules" / "gltf-validator"))
      << "the glTF validator is not installed: run scripts/install-deps (npm ci in scripts/gltf-validate)";
  std::vector<std::string> files;
  for (const std::string scene : {"cloth_door", "plant_pot", "toy_dashboard"}) {
    files.push_back(path(scene + ".glb"));
    exported({(kTestData / "packages" / (scene + ".h5")).string(), "-o", files.back(), "--recording",
              (kTestData / "recordings" / (scene + ".phcrec")).string()});
  }
  files.push_back(path("plate.glb"));
  exported({path("plate.h5"), "-o", files.back()});
  testing::PlateOptions grey;
  grey.appearance = false;
  auto no_appearance = testing::make_plate_package(grey);
  write(no_appearance, "grey.h5");
  testing::write_recording(dir_ / "grey.rec", "plate", "grey.h5", core::file_content_hash(dir_ / "grey.h5"),
                           testing::irf_stream(no_appearance, 1));
  files.push_back(path("grey.glb"));
  exported({path("grey.h5"), "-o", files.back(), "--recording", path("grey.rec")});
  write(plate_with_world_board(), "board.h5");
  record("board.rec", "board.h5");
  files.push_back(path("board.glb"));
  exported({path("board.h5"), "-o", files.back(), "--recording", path("board.rec")});
  write(loose_plate(), "loose.h5");
  record("loose.rec", "loose.h5");
  files.push_back(path("loose.glb"));
  exported({path("loose.h5"), "-o", files.back(), "--recording", path("loose.rec")});

  std::string command = "node '" + kValidator.string() + "' --strict";
  for (const auto& f : files) command += " '" + f + "'";
  const auto r = run_command(command);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const auto& f : files)
    EXPECT_THAT(r.output, HasSubstr(f + ": 0 errors, 0 warnings, 0 infos, 0 hints")) << r.output;
  std::cout << r.output;  // the report, in the test log
}

// Reads an accessor of 4-byte components as floats (tinygltf only parses).
std::vector<float> floats_of(const tinygltf::Model& m, int accessor) {
  const auto& a = m.accessors[static_cast<std::size_t>(accessor)];
  const auto& v = m.bufferViews[static_cast<std::size_t>(a.bufferView)];
  const auto* begin = reinterpret_cast<const float*>(m.buffers[0].data.data() + v.byteOffset + a.byteOffset);
  return {begin, begin + a.count * static_cast<std::size_t>(
                                       tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type)))};
}

int node_named(const tinygltf::Model& m, const std::string& name) {
  for (std::size_t i = 0; i < m.nodes.size(); ++i) {
    if (m.nodes[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

// The animated value of `path` on `node` at keyframe `key`.
std::vector<float> keyframe(const tinygltf::Model& m, int node, const std::string& path, std::size_t key) {
  const auto& anim = m.animations.at(0);
  for (const auto& ch : anim.channels) {
    if (ch.target_node != node || ch.target_path != path) continue;
    const auto& sampler = anim.samplers[static_cast<std::size_t>(ch.sampler)];
    const auto values = floats_of(m, sampler.output);
    const std::size_t per_key = values.size() / m.accessors[static_cast<std::size_t>(sampler.input)].count;
    const auto first = values.begin() + static_cast<std::ptrdiff_t>(key * per_key);
    return {first, first + static_cast<std::ptrdiff_t>(per_key)};
  }
  return {};
}

int parent_of(const tinygltf::Model& m, int node) {
  for (std::size_t i = 0; i < m.nodes.size(); ++i) {
    const auto& c = m.nodes[i].children;
    if (std::find(c.begin(), c.end(), node) != c.end()) return static_cast<int>(i);
  }
  return -1;
}

// What a viewer shows of the mesh of `node` at keyframe `key`: POSITION plus
// the animated morph weights times the targets, then the animated translation
// and rotation of its parent (the support node) when it has one. 3 per vertex.
std::vector<double> evaluated(const tinygltf::Model& m, int node, std::size_t key) {
  const auto& prim =
      m.meshes[static_cast<std::size_t>(m.nodes[static_cast<std::size_t>(node)].mesh)].primitives.at(0);
  const auto position = floats_of(m, prim.attributes.at("POSITION"));
  std::vector<double> x(position.begin(), position.end());
  const auto w = keyframe(m, node, "weights", key);
  EXPECT_EQ(w.size(), prim.targets.size()) << m.nodes[static_cast<std::size_t>(node)].name;
  for (std::size_t k = 0; k < w.size() && k < prim.targets.size(); ++k) {
    const auto target = floats_of(m, prim.targets[k].at("POSITION"));
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += double(w[k]) * target[i];
  }
  if (const int parent = parent_of(m, node); parent >= 0) {
    const auto tr = keyframe(m, parent, "translation", key), rot = keyframe(m, parent, "rotation", key);
    EXPECT_EQ(tr.size(), 3u);
    EXPECT_EQ(rot.size(), 4u);
    const Eigen::Quaterniond q(rot.at(3), rot.at(0), rot.at(1), rot.at(2));
    for (std::size_t v = 0; v < x.size() / 3; ++v) {
      const Eigen::Vector3d y = q * Eigen::Vector3d(x[3 * v], x[3 * v + 1], x[3 * v + 2]) +
                                Eigen::Vector3d(tr.at(0), tr.at(1), tr.at(2));
      for (int c = 0; c < 3; ++c) x[3 * v + static_cast<std::size_t>(c)] = y[c];
    }
  }
  return x;
}

// Scene points with the given `attached` flag, in scene order: vertex i of
// the mesh of that kind is the i-th of them (docs/gltf.md).
std::vector<std::size_t> points_with(const core::ScenePackage& p, std::uint8_t attached) {
  std::vector<std::size_t> points;
  for (std::size_t i = 0; i < p.mesh.attached.size(); ++i) {
    if (p.mesh.attached[i] == attached) points.push_back(i);
  }
  return points;
}

// The mesh of `node` at keyframe `key` against eq. 7 (and the support
// transform for attached points) at the matching scene points, 1e-5.
void expect_eq7(const tinygltf::Model& m, int node, std::size_t key, const std::vector<double>& expected,
                const std::vector<std::size_t>& points) {
  const auto x = evaluated(m, node, key);
  ASSERT_EQ(x.size(), 3 * points.size()) << m.nodes[static_cast<std::size_t>(node)].name;
  for (std::size_t v = 0; v < points.size(); ++v) {
    for (std::size_t c = 0; c < 3; ++c)
      EXPECT_NEAR(x[3 * v + c], expected[3 * points[v] + c], 1e-5)
          << "vertex " << v << ", point " << points[v];
  }
}

TEST_F(GltfExport, TinygltfReadsBackEq7AtARecordedFrame) {
  const auto board = plate_with_world_board();
  const auto hash = write(board, "board.h5");
  record("board.rec", "board.h5", 3);
  exported({path("board.h5"), "-o", path("board.glb"), "--recording", path("board.rec")});

  const tinygltf::Model m = load("board.glb");
  const int support = node_named(m, "support"), world = node_named(m, "plate (world)");
  ASSERT_GE(support, 0);
  ASSERT_GE(world, 0);
  const int attached = m.nodes[static_cast<std::size_t>(support)].children.at(0);
  const auto& plate = m.meshes[static_cast<std::size_t>(m.nodes[static_cast<std::size_t>(attached)].mesh)];
  const auto& fixed = m.meshes[static_cast<std::size_t>(m.nodes[static_cast<std::size_t>(world)].mesh)];
  ASSERT_EQ(plate.primitives.at(0).targets.size(), 4u);  // r_u
  EXPECT_TRUE(fixed.primitives.at(0).targets.empty());   // the board does not deform
  EXPECT_EQ(parent_of(m, world), -1);                    // a root node: it stays where it is
  EXPECT_EQ(m.accessors[static_cast<std::size_t>(m.animations.at(0).samplers.at(0).input)].count, 90u);

  // Frame 45: mean + sum_k w_k target_k, then the support node's TRS for the
  // plate; the board as it is, against the rows of its points.
  const std::size_t t = 45;
  const auto frame = testing::irf_stream(board, 3)[t];
  const std::vector<float> q_u(frame.q_u().begin(), frame.q_u().end());
  EXPECT_EQ(keyframe(m, attached, "weights", t), q_u);
  const auto expected = cpu_positions(basis_from_package(board, hash), q_u,
                                      std::vector<float>(frame.support().begin(), frame.support().end()));
  const auto rows_of_plate = points_with(board, 1), rows_of_board = points_with(board, 0);
  ASSERT_EQ(rows_of_board.size(), 4u);  // the 4 board corners
  expect_eq7(m, attached, t, expected, rows_of_plate);
  expect_eq7(m, world, t, expected, rows_of_board);

  // Nothing attached: the world mesh carries the targets and no support node moves it.
  const auto loose = loose_plate();
  const auto loose_hash = write(loose, "loose.h5");
  record("loose.rec", "loose.h5", 3);
  exported({path("loose.h5"), "-o", path("loose.glb"), "--recording", path("loose.rec")});
  const tinygltf::Model l = load("loose.glb");
  EXPECT_EQ(node_named(l, "support"), -1);
  const int whole = node_named(l, "plate (world)");
  ASSERT_GE(whole, 0);
  EXPECT_EQ(keyframe(l, whole, "weights", t), q_u);
  const auto loose_expected =
      cpu_positions(basis_from_package(loose, loose_hash), q_u,
                    std::vector<float>(frame.support().begin(), frame.support().end()));
  expect_eq7(l, whole, t, loose_expected, points_with(loose, 0));
}

// COLOR_0 is what phasecast-render shows at rest: without an appearance
// model, the shader's grey diffuse fallback, which under the white light
// (L_0 = 4 pi Y_0) is 0.7 / pi * pi Y_0 * 4 pi Y_0 = 0.7 for every normal;
// with one, sum_k M_bar[48p + 16c + k] L_c,k, here under "sun", whose light
// has all 16 coefficients, clamped to [0, 1].
TEST_F(GltfExport, ColoursAreTheRenderersAtRest) {
  testing::PlateOptions grey;
  grey.appearance = false;
  write(testing::make_plate_package(grey), "grey.h5");
  EXPECT_THAT(exported({path("grey.h5"), "-o", path("grey.glb"), "--light", "white"}).out,
              HasSubstr("colours from the grey diffuse fallback"));
  const tinygltf::Model g = load("grey.glb");
  std::size_t values = 0;
  for (const auto& mesh : g.meshes) {
    for (const float c : floats_of(g, mesh.primitives.at(0).attributes.at("COLOR_0"))) {
      EXPECT_FLOAT_EQ(c, 0.7f);
      ++values;
    }
  }
  EXPECT_EQ(values, 3u * static_cast<std::size_t>(package_.mesh.points()));

  const auto board = plate_with_world_board();
  write(board, "board.h5");
  exported({path("board.h5"), "-o", path("board.glb"), "--light", "sun"});
  const tinygltf::Model m = load("board.glb");
  const ShLight sun = light_probe("sun");
  const auto& M = board.appearance->mean_transfer;
  int values_checked = 0, beyond_k0 = 0;  // beyond_k0: colours the coefficients k > 0 change by > 1e-3
  for (const auto& [name, flag] : {std::pair<std::string, std::uint8_t>{"plate", 1}, {"plate (world)", 0}}) {
    const int node = node_named(m, name);
    ASSERT_GE(node, 0) << name;
    const auto& prim =
        m.meshes[static_cast<std::size_t>(m.nodes[static_cast<std::size_t>(node)].mesh)].primitives.at(0);
    const auto colours = floats_of(m, prim.attributes.at("COLOR_0"));
    const auto points = points_with(board, flag);
    ASSERT_EQ(colours.size(), 3 * points.size()) << name;
    for (std::size_t v = 0; v < points.size(); ++v) {
      for (std::size_t c = 0; c < 3; ++c) {
        double sum = 0;
        for (std::size_t k = 0; k < 16; ++k)
          sum += double(M[static_cast<Eigen::Index>(48 * points[v] + 16 * c + k)]) * sun.coefficients[c][k];
        const double k0 =
            double(M[static_cast<Eigen::Index>(48 * points[v] + 16 * c)]) * sun.coefficients[c][0];
        EXPECT_NEAR(colours[3 * v + c], std::clamp(sum, 0.0, 1.0), 1e-5) << name << " vertex " << v;
        ++values_checked;
        if (std::abs(std::clamp(sum, 0.0, 1.0) - std::clamp(k0, 0.0, 1.0)) > 1e-3) ++beyond_k0;
      }
    }
  }
  EXPECT_EQ(values_checked, 3 * package_.mesh.points());
  EXPECT_GT(2 * beyond_k0, values_checked)
      << "the coefficients k > 0 hardly matter: M_bar is checked at k = 0 only";
}

// The scene's [view] where the tool's flags are absent: its camera becomes
// the "scene camera" node (at the eye, looking at the target along its
// local -z, the view's field of view) and its light colours the points.
TEST_F(GltfExport, TheScenesViewGivesTheCameraAndTheLight) {
  auto viewed = package_;
  viewed.attributes.camera = std::array<float, 10>{1, 2, 3, 0, 0.5f, 0, 0, 1, 0, 30};
  viewed.attributes.light = "sun";
  write(viewed, "viewed.h5");
  exported({path("viewed.h5"), "-o", path("viewed.glb")});
  exported({path("viewed.h5"), "-o", path("sun.glb"), "--light", "sun"});
  exported({path("viewed.h5"), "-o", path("grace.glb"), "--light", "grace"});
  const tinygltf::Model m = load("viewed.glb");
  const int node = node_named(m, "scene camera");
  ASSERT_GE(node, 0);
  const auto& n = m.nodes[static_cast<std::size_t>(node)];
  ASSERT_EQ(n.translation.size(), 3u);
  EXPECT_NEAR(n.translation[0], 1, 1e-6);
  EXPECT_NEAR(n.translation[1], 2, 1e-6);
  EXPECT_NEAR(n.translation[2], 3, 1e-6);
  ASSERT_EQ(n.rotation.size(), 4u);
  const Eigen::Quaterniond q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
  const Eigen::Vector3d looks = q * Eigen::Vector3d(0, 0, -1), up = q * Eigen::Vector3d(0, 1, 0);
  const Eigen::Vector3d towards = (Eigen::Vector3d(0, 0.5, 0) - Eigen::Vector3d(1, 2, 3)).normalized();
  EXPECT_NEAR(looks.dot(towards), 1, 1e-6);
  EXPECT_GT(up.y(), 0.9) << "the view's up is +y";
  const auto& camera = m.cameras.at(static_cast<std::size_t>(n.camera));
  EXPECT_NEAR(camera.perspective.yfov, 30 * std::numbers::pi / 180, 1e-6);
  const auto colours = [&](const tinygltf::Model& g) {
    return floats_of(g, g.meshes.at(0).primitives.at(0).attributes.at("COLOR_0"));
  };
  EXPECT_EQ(colours(m), colours(load("sun.glb"))) << "the view's light colours the points";
  EXPECT_NE(colours(m), colours(load("grace.glb")));
}

TEST_F(GltfExport, AnimatesTheRequestedInstance) {
  auto frames = testing::irf_stream(package_, 0, 1);
  auto second = testing::irf_stream(package_, 2, 7);
  second.resize(30);
  frames.insert(frames.end(), second.begin(), second.end());
  testing::write_recording(dir_ / "two.rec", "plate", "plate.h5", core::file_content_hash(dir_ / "plate.h5"),
                           frames);
  EXPECT_THAT(exported({path("plate.h5"), "-o", path("a.glb"), "--recording", path("two.rec")}).out,
              HasSubstr("animation of instance 1: 90 frames"));
  const auto r =
      exported({path("plate.h5"), "-o", path("b.glb"), "--recording", path("two.rec"), "--instance", "7"});
  EXPECT_THAT(r.out, HasSubstr("animation of instance 7: 30 frames from frame 0"));
  EXPECT_THAT(r.out, HasSubstr("a vertex cache of the same session: 1020 bytes/frame"));  // 12 S, S = 85
}

TEST_F(GltfExport, TrianglesAcrossAttachmentAreCountedNotExported) {
  auto p = testing::make_plate_package();
  p.mesh.attached[0] = 0;  // a plate corner fixed in the world: its triangle joins both kinds
  write(p, "mixed.h5");
  GltfExportOptions o;
  o.package = dir_ / "mixed.h5";
  o.out = dir_ / "mixed.glb";
  const auto s = export_gltf(o);
  EXPECT_EQ(s.dropped_triangles, 2);  // the corner is in two triangles of the grid
  EXPECT_EQ(s.triangles, p.mesh.triangle_count() - 2);
  EXPECT_THAT(describe(s, dir_ / "mixed.glb"), HasSubstr("2 triangles join attached and world points"));
}

TEST_F(GltfExport, HelpNamesTheOptions) {
  const auto r = testing::run_tool("phasecast-export", {"--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* flag : {"--out", "--recording", "--instance", "--light"})
    EXPECT_THAT(r.out, HasSubstr(flag));
}

TEST_F(GltfExport, BadInputsGiveOneLineErrors) {
  const std::string out = path("out.glb");
  record("s.rec", "plate.h5");
  EXPECT_THAT(one_line_error({path("missing.h5"), "-o", out}), HasSubstr("missing.h5"));
  EXPECT_THAT(one_line_error({path("plate.h5"), "-o", out, "--recording", path("missing.rec")}),
              HasSubstr("missing.rec"));
  EXPECT_EQ(one_line_error({path("plate.h5"), "-o", out, "--recording", path("s.rec"), "--instance", "9"}),
            fmt::format("phasecast-export: recording {}: no frames of instance 9 (expected one of 1: the "
                        "instances of scene 'plate' it holds)\n",
                        path("s.rec")));
  EXPECT_EQ(
      one_line_error({path("plate.h5"), "-o", path("out.gltf")}),
      fmt::format("phasecast-export: -o {}: only binary glTF is written (expected a path ending in .glb)\n",
                  path("out.gltf")));
  EXPECT_EQ(one_line_error({path("plate.h5"), "-o", path("no/such/dir/out.glb")}),
            fmt::format("phasecast-export: {}: cannot be written (expected a writable path in an existing "
                        "folder)\n",
                        path("no/such/dir/out.glb")));
  // A folder where the file should go: the temporary file is written, the
  // rename fails, and the message is the rename's.
  std::filesystem::create_directory(dir_ / "adir.glb");
  EXPECT_EQ(
      one_line_error({path("plate.h5"), "-o", path("adir.glb")}),
      fmt::format("phasecast-export: {}: cannot be written (Is a directory; expected a path to a file in a "
                  "writable folder)\n",
                  path("adir.glb")));
  EXPECT_TRUE(std::filesystem::is_empty(dir_ / "adir.glb"));
  EXPECT_EQ(one_line_error({path("plate.h5"), "-o", out, "--light", "moon"}),
            "phasecast-export: light probe 'moon' is unknown (expected one of grace, sky, sun, white)\n");
  // Bad usage: exit status 2.
  EXPECT_THAT(one_line_error({path("plate.h5")}, 2), HasSubstr("--out is required"));
  EXPECT_THAT(one_line_error({path("plate.h5"), "-o", out, "--instance", "1"}, 2), HasSubstr("--recording"));
  EXPECT_THAT(
      one_line_error({path("plate.h5"), "-o", out, "--instance", "one", "--recording", path("s.rec")}, 2),
      HasSubstr("--instance"));
}

// A failed export leaves a file already at the output path as it was.
TEST_F(GltfExport, FailureLeavesAnExistingFileUntouched) {
  record("s.rec", "plate.h5");
  exported({path("plate.h5"), "-o", path("kept.glb")});
  const std::string before = testing::read_file(dir_ / "kept.glb");
  ASSERT_GT(before.size(), 1000u);
  EXPECT_THAT(one_line_error({path("plate.h5"), "-o", path("kept.glb"), "--recording", path("s.rec"),
                              "--instance", "9"}),
              HasSubstr("no frames of instance 9"));
  EXPECT_EQ(testing::read_file(dir_ / "kept.glb"), before);
}

// A recorded support transform that is not rigid cannot be a node's TRS; but
// without attached points there is no support node, and it moves nothing.
TEST_F(GltfExport, SupportIsCheckedOnlyWhenThereIsASupportNode) {
  auto stream = testing::irf_stream(package_, 3);
  for (auto& f : stream) {
    for (int i = 0; i < 12; ++i) {
      if (i % 4 != 3) f.set_support(i, 2 * f.support(i));  // R scaled by 2: not a rotation
    }
  }
  testing::write_recording(dir_ / "scaled.rec", "plate", "plate.h5",
                           core::file_content_hash(dir_ / "plate.h5"), stream);
  EXPECT_THAT(one_line_error({path("plate.h5"), "-o", path("out.glb"), "--recording", path("scaled.rec")}),
              HasSubstr("frame 0: the support transform is not rigid"));
  write(loose_plate(), "loose.h5");
  testing::write_recording(dir_ / "loose.rec", "plate", "loose.h5",
                           core::file_content_hash(dir_ / "loose.h5"), stream);
  EXPECT_THAT(exported({path("loose.h5"), "-o", path("loose.glb"), "--recording", path("loose.rec")}).out,
              HasSubstr("animation of instance 1: 90 frames"));
  const tinygltf::Model m = load("loose.glb");
  ASSERT_EQ(m.animations.size(), 1u);
  for (const auto& ch : m.animations[0].channels) EXPECT_EQ(ch.target_path, "weights");
}

// Nothing deformable and nothing attached: no animation is written, and the
// summary says so instead of describing one.
TEST_F(GltfExport, NothingMovesNoAnimation) {
  auto still = loose_plate();
  std::fill(still.mesh.deformable.begin(), still.mesh.deformable.end(), 0);
  still.reduction.U_u.setZero();  // static points have zero rows
  write(still, "still.h5");
  record("still.rec", "still.h5");
  const auto r = exported({path("still.h5"), "-o", path("still.glb"), "--recording", path("still.rec")});
  EXPECT_THAT(r.out, HasSubstr("phasecast-export: no animation: nothing in scene 'plate' moves"));
  EXPECT_THAT(r.out, HasSubstr("the 90 frames of instance 1 were read but not written"));
  EXPECT_THAT(r.out, Not(HasSubstr("animation of instance")));
  const tinygltf::Model m = load("still.glb");
  EXPECT_TRUE(m.animations.empty());
  for (const auto& mesh : m.meshes) EXPECT_TRUE(mesh.primitives.at(0).targets.empty());
}

TEST_F(GltfExport, RecordingOfAnotherPackageIsRejected) {
  const std::string out = path("out.glb");
  const auto hash = core::file_content_hash(dir_ / "plate.h5");
  testing::write_recording(dir_ / "other.rec", "plate", "plate.h5", hash + 1,
                           testing::irf_stream(package_, 0));
  EXPECT_EQ(
      one_line_error({path("plate.h5"), "-o", out, "--recording", path("other.rec")}),
      fmt::format("phasecast-export: recording {}: scene 'plate' was recorded with package hash {:016x}, "
                  "but {} has hash {:016x} (expected the same package file)\n",
                  path("other.rec"), hash + 1, path("plate.h5"), hash));
  // Another scene altogether: the committed plant recording against the cloth package.
  const auto cloth = (kTestData / "packages" / "cloth_door.h5").string();
  const auto plant = (kTestData / "recordings" / "plant_pot.phcrec").string();
  EXPECT_EQ(
      one_line_error({cloth, "-o", out, "--recording", plant}),
      fmt::format("phasecast-export: recording {}: no scene 'cloth_door_tiny' (expected the scene of {}; it "
                  "records 'plant_pot_tiny')\n",
                  plant, cloth));
  // Same package, but a frame with one q_u value too many: the rank does not match.
  auto stream = testing::irf_stream(package_, 0);
  stream[3].add_q_u(1.0f);
  testing::write_recording(dir_ / "rank.rec", "plate", "plate.h5", hash, stream);
  EXPECT_EQ(one_line_error({path("plate.h5"), "-o", out, "--recording", path("rank.rec")}),
            fmt::format("phasecast-export: recording {}: frame 3: q_u has 5 values (expected r_u = 4)\n",
                        path("rank.rec")));
}

}  // namespace
}  // namespace phasecast::client
