// phasecast-export as a user runs it: the files pass the Khronos glTF
// validator (npm, scripts/gltf-validate), tinygltf reads them back into eq. 7
// at a recorded frame, the instance is the one asked for, and bad inputs give
// one-line errors. The independent reader (h5py, struct) is
// check_gltf_export.py.

#include "phasecast/client/gltf_export.h"
#include "phasecast/client/client_basis.h"
#include "phasecast/core/hash.h"
#include "run_tool.h"
#include "synthetic_package.h"
#include "test_peer.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>
#include <Eigen/Geometry>

#include <sys/wait.h>
#include <cstdio>
#include <cstdlib>

namespace phasecast::client {
namespace {

using ::testing::HasSubstr;

const std::filesystem::path kSourceDir = PHASECAST_SOURCE_DIR;
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
  // and no output file left behind.
  std::string one_line_error(const std::vector<std::string>& args, int code = 1) const {
    const auto r = testing::run_tool("phasecast-export", args);
    EXPECT_EQ(r.exit_code, code) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "out.glb"));
    return r.err;
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
  auto loose = testing::make_plate_package();  // nothing attached: one world mesh with the targets
  std::fill(loose.mesh.attached.begin(), loose.mesh.attached.end(), 0);
  write(loose, "loose.h5");
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

TEST_F(GltfExport, TinygltfReadsBackEq7AtARecordedFrame) {
  const auto board = plate_with_world_board();
  const auto hash = write(board, "board.h5");
  record("board.rec", "board.h5", 3);
  exported({path("board.h5"), "-o", path("board.glb"), "--recording", path("board.rec")});

  tinygltf::Model m;
  std::string err, warn;
  ASSERT_TRUE(tinygltf::TinyGLTF().LoadBinaryFromFile(&m, &err, &warn, path("board.glb"))) << err;
  const int support = node_named(m, "support"), world = node_named(m, "plate (world)");
  ASSERT_GE(support, 0);
  ASSERT_GE(world, 0);
  const int attached = m.nodes[static_cast<std::size_t>(support)].children.at(0);
  const auto& plate = m.meshes[static_cast<std::size_t>(m.nodes[static_cast<std::size_t>(attached)].mesh)];
  const auto& fixed = m.meshes[static_cast<std::size_t>(m.nodes[static_cast<std::size_t>(world)].mesh)];
  ASSERT_EQ(plate.primitives.at(0).targets.size(), 4u);  // r_u
  EXPECT_TRUE(fixed.primitives.at(0).targets.empty());   // the board does not deform
  EXPECT_EQ(m.accessors[static_cast<std::size_t>(m.animations.at(0).samplers.at(0).input)].count, 90u);

  // Frame 45: mean + sum_k w_k target_k, then the support node's TRS.
  const std::size_t t = 45;
  const auto w = keyframe(m, attached, "weights", t), tr = keyframe(m, support, "translation", t),
             rot = keyframe(m, support, "rotation", t);
  const auto frame = testing::irf_stream(board, 3)[t];
  EXPECT_EQ(w, std::vector<float>(frame.q_u().begin(), frame.q_u().end()));
  const Eigen::Quaterniond q(rot[3], rot[0], rot[1], rot[2]);
  const auto& prim = plate.primitives[0];
  auto position = floats_of(m, prim.attributes.at("POSITION"));
  for (std::size_t k = 0; k < w.size(); ++k) {
    const auto target = floats_of(m, prim.targets[k].at("POSITION"));
    for (std::size_t i = 0; i < position.size(); ++i) position[i] += w[k] * target[i];
  }
  const auto expected = cpu_positions(basis_from_package(board, hash), w,
                                      std::vector<float>(frame.support().begin(), frame.support().end()));
  for (std::size_t v = 0; v < position.size() / 3; ++v) {  // the attached points come first in the plate
    const Eigen::Vector3d x = q * Eigen::Vector3d(position[3 * v], position[3 * v + 1], position[3 * v + 2]) +
                              Eigen::Vector3d(tr[0], tr[1], tr[2]);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(x[c], expected[3 * v + static_cast<std::size_t>(c)], 1e-5) << v;
  }
  EXPECT_EQ(floats_of(m, fixed.primitives[0].attributes.at("POSITION")).size(), 12u);  // the 4 board corners
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
  EXPECT_EQ(one_line_error({path("plate.h5"), "-o", out, "--light", "moon"}),
            "phasecast-export: light probe 'moon' is unknown (expected one of grace, sky, sun, white)\n");
  // Bad usage: exit status 2.
  EXPECT_THAT(one_line_error({path("plate.h5")}, 2), HasSubstr("--out is required"));
  EXPECT_THAT(one_line_error({path("plate.h5"), "-o", out, "--instance", "1"}, 2), HasSubstr("--recording"));
  EXPECT_THAT(
      one_line_error({path("plate.h5"), "-o", out, "--instance", "one", "--recording", path("s.rec")}, 2),
      HasSubstr("--instance"));
}

TEST_F(GltfExport, RecordingOfAnotherPackageIsRejected) {
  const std::string out = path("out.glb");
  const auto hash = core::file_content_hash(dir_ / "plate.h5");
  testing::write_recording(dir_ / "other.rec", "plate", "plate.h5", hash + 1,
                           testing::irf_stream(package_, 0));
  EXPECT_EQ(one_line_error({path("plate.h5"), "-o", out, "--recording", path("other.rec")}),
            fmt::format("phasecast-export: recording {} was made with package hash {:016x}, but {} has hash "
                        "{:016x} (expected the same package)\n",
                        path("other.rec"), hash + 1, path("plate.h5"), hash));
  // Another scene altogether: the committed plant recording against the cloth package.
  const auto cloth = (kTestData / "packages" / "cloth_door.h5").string();
  const auto plant = (kTestData / "recordings" / "plant_pot.phcrec").string();
  EXPECT_EQ(one_line_error({cloth, "-o", out, "--recording", plant}),
            fmt::format("phasecast-export: recording {} has no scene 'cloth_door_tiny' (the scene of {}; it "
                        "records: plant_pot_tiny)\n",
                        plant, cloth));
  // Same package, but a frame with one q_u value too many: the rank does not match.
  auto stream = testing::irf_stream(package_, 0);
  stream[3].add_q_u(1.0f);
  testing::write_recording(dir_ / "rank.rec", "plate", "plate.h5", hash, stream);
  EXPECT_EQ(
      one_line_error({path("plate.h5"), "-o", out, "--recording", path("rank.rec")}),
      fmt::format("phasecast-export: {}: frame 3: q_u has 5 values (expected r_u = 4)\n", path("rank.rec")));
}

}  // namespace
}  // namespace phasecast::client
