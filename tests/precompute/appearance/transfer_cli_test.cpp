// `phasecast-precompute transfer` as a user runs it: output file contents,
// exit codes and one-line errors.

#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/precompute/appearance/transfer_file.h"
#include "run_tool.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

namespace phasecast {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

// Unit cube, 8 shared vertices, quads (triangulated by the reader).
constexpr const char* kCubeObj = R"(# cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
)";

class TransferCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("transfer_cli_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    write("cube.obj", kCubeObj);
  }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(dir_ / name) << text;
    return (dir_ / name).string();
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static int lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }
  // Runs the tool expecting failure; returns its single stderr line.
  static std::string failure(const std::vector<std::string>& args) {
    const auto r = testing::run_tool("phasecast-precompute", args);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    return r.err;
  }

  std::filesystem::path dir_;
};

TEST_F(TransferCli, HelpDescribesTheCommand) {
  const auto r = testing::run_tool("phasecast-precompute", {"transfer", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("--mode"));
  EXPECT_THAT(r.out, HasSubstr("--albedo"));
}

TEST_F(TransferCli, WritesTheTransferOfTheMesh) {
  const auto r =
      testing::run_tool("phasecast-precompute",
                        {"transfer", path("cube.obj"), "-o", path("t.h5"), "--mode", "interreflected",
                         "--rays", "256", "--bounces", "1", "--albedo", "0.5,0.6,0.7", "--threads", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("transfer: 8 points, interreflected mode, 256 rays"));
  const auto file = precompute::read_transfer_file(path("t.h5"));
  EXPECT_EQ(file.options.mode, precompute::TransferMode::interreflected);
  EXPECT_EQ(file.options.rays, 256);
  EXPECT_EQ(file.options.bounces, 1);
  EXPECT_EQ(file.options.albedo, (std::array<float, 3>{0.5f, 0.6f, 0.7f}));
  const auto mesh = precompute::load_obj_mesh(path("cube.obj"));
  EXPECT_EQ(file.positions, mesh.positions);
  EXPECT_EQ(file.normals, mesh.normals);
  EXPECT_EQ(file.transfer, precompute::compute_transfer(mesh.positions, mesh.triangles, mesh.normals,
                                                        file.options));  // bit-identical
  // A corner of the cube: its normal is the diagonal, and the cube hides part of its hemisphere.
  EXPECT_NEAR(file.normals.row(0).norm(), 1.0f, 1e-6f);
  EXPECT_LT(file.normals(0, 0), 0);
}

TEST_F(TransferCli, DoubleSidedAddsBackFacePoints) {
  const auto r = testing::run_tool("phasecast-precompute", {"transfer", path("cube.obj"), "-o", path("t.h5"),
                                                            "--rays", "64", "--double-sided", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const auto file = precompute::read_transfer_file(path("t.h5"));
  ASSERT_EQ(file.positions.rows(), 16);
  EXPECT_EQ(file.positions.bottomRows(8), file.positions.topRows(8));
  EXPECT_EQ(file.normals.bottomRows(8), -file.normals.topRows(8));
  // The inner side of a closed cube sees only the cube: no direct light.
  EXPECT_EQ(file.transfer.bottomRows(8).cwiseAbs().maxCoeff(), 0.0f);
  EXPECT_EQ(file.options.mode, precompute::TransferMode::shadowed);
}

TEST_F(TransferCli, RejectsAMissingMesh) {
  EXPECT_EQ(failure({"transfer", path("none.obj"), "-o", path("t.h5")}),
            "phasecast-precompute: " + path("none.obj") + ": no such mesh file\n");
  EXPECT_FALSE(std::filesystem::exists(path("t.h5")));
}

TEST_F(TransferCli, RejectsAMeshWithoutFaces) {
  write("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  EXPECT_EQ(failure({"transfer", path("points.obj"), "-o", path("t.h5")}),
            "phasecast-precompute: " + path("points.obj") + ": expected at least one face, found none\n");
}

TEST_F(TransferCli, RejectsAFaceOutsideTheVertices) {
  write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
  EXPECT_EQ(failure({"transfer", path("bad.obj"), "-o", path("t.h5")}),
            "phasecast-precompute: " + path("bad.obj") + ": face refers to vertex 7, expected 1..3\n");
}

TEST_F(TransferCli, RejectsAnUnknownMode) {
  EXPECT_EQ(failure({"transfer", path("cube.obj"), "-o", path("t.h5"), "--mode", "glossy"}),
            "phasecast-precompute: unknown transfer mode 'glossy' (expected unshadowed, shadowed or "
            "interreflected)\n");
}

TEST_F(TransferCli, RejectsABadAlbedo) {
  EXPECT_EQ(failure({"transfer", path("cube.obj"), "-o", path("t.h5"), "--albedo", "0.5,0.5"}),
            "phasecast-precompute: --albedo '0.5,0.5': expected three numbers R,G,B in [0, 1]\n");
  EXPECT_EQ(failure({"transfer", path("cube.obj"), "-o", path("t.h5"), "--albedo", "0.5,x,0.5"}),
            "phasecast-precompute: --albedo '0.5,x,0.5': expected three numbers R,G,B in [0, 1]\n");
  EXPECT_EQ(failure({"transfer", path("cube.obj"), "-o", path("t.h5"), "--albedo", "1.5,0.5,0.5"}),
            "phasecast-precompute: transfer: albedo channel 0 must be in [0, 1], got 1.5\n");
}

TEST_F(TransferCli, RejectsZeroRays) {
  EXPECT_EQ(failure({"transfer", path("cube.obj"), "-o", path("t.h5"), "--rays", "0"}),
            "phasecast-precompute: transfer: rays must be in 1..1048576, got 0\n");
}

TEST_F(TransferCli, RejectsAnUnwritableOutput) {
  EXPECT_THAT(
      failure({"transfer", path("cube.obj"), "-o", path("no/such/dir/t.h5"), "--rays", "8", "-q"}),
      StartsWith("phasecast-precompute: " + path("no/such/dir/t.h5") + ": cannot write transfer file"));
}

TEST_F(TransferCli, LoadsAndTriangulatesTheObj) {
  const auto mesh = precompute::load_obj_mesh(path("cube.obj"));
  EXPECT_EQ(mesh.positions.rows(), 8);
  EXPECT_EQ(mesh.triangles.rows(), 12);  // six quads
  // Corner (0, 0, 0): three faces of equal area meet, the normal is the outward diagonal.
  EXPECT_LT((mesh.normals.row(0) + Eigen::RowVector3f::Constant(1.0f / std::sqrt(3.0f))).norm(), 1e-6f);
}

TEST(TransferFile, RejectsMismatchedContents) {
  precompute::TransferFile file;
  file.positions = MatrixXfR::Zero(3, 3);
  file.normals = MatrixXfR::Zero(3, 3);
  file.transfer = MatrixXfR::Zero(2, 48);
  try {
    precompute::write_transfer_file(file, "unused.h5");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "unused.h5: transfer file needs S x 3 positions and normals and S x 48 transfer");
  }
}

TEST(TransferFile, RejectsFilesThatAreNotTransferFiles) {
  const auto dir = testing::scratch_dir("transfer_file_rejects");
  try {
    precompute::read_transfer_file(dir / "none.h5");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "none.h5").string() + ": no such transfer file");
  }
  std::ofstream(dir / "text.h5") << "not hdf5";
  try {
    precompute::read_transfer_file(dir / "text.h5");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "text.h5").string() + ": not an HDF5 file (or truncated)");
  }
}

}  // namespace
}  // namespace phasecast
