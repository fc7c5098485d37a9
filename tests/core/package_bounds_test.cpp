// Issue 18: a package header declaring a dataset far larger than the file
// ended in a bare std::bad_alloc. The reader must refuse every such package
// with one PackageError line naming the file, the dataset and what was
// expected, before it allocates anything for the data.

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/package.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>

namespace phasecast {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::Not;

using testing::package_rejection;

// Raw HDF5 C API calls, so the tests can write what our writer never would.
class RawFile {
 public:
  explicit RawFile(const std::filesystem::path& path)
      : id_(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT)) {
    EXPECT_GE(id_, 0) << path;
  }
  ~RawFile() { H5Fclose(id_); }
  RawFile(const RawFile&) = delete;
  RawFile& operator=(const RawFile&) = delete;

  // Replaces dataset `name` by one declaring `dims` of `type`, chunked and
  // never written: the header promises data the file lacks.
  void declare(const std::string& name, hid_t type, const std::vector<hsize_t>& dims) {
    std::vector<hsize_t> chunk(dims.size(), 1);
    for (size_t i = 1; i < dims.size(); ++i) chunk[i] = std::min<hsize_t>(dims[i], 1024);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    EXPECT_GE(H5Pset_chunk(dcpl, static_cast<int>(chunk.size()), chunk.data()), 0);
    create(name, type, dims, dcpl);
    H5Pclose(dcpl);
  }

  // Replaces root attribute `name` by an array of fixed-length strings.
  void string_array_attribute(const std::string& name, const std::vector<std::string>& values, size_t width) {
    EXPECT_GE(H5Adelete(id_, name.c_str()), 0) << name;
    std::string packed;
    for (const auto& v : values) packed += v + std::string(width - v.size(), '\0');
    const hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, width);
    const hsize_t n = values.size();
    const hid_t space = H5Screate_simple(1, &n, nullptr);
    const hid_t attr = H5Acreate2(id_, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT);
    EXPECT_GE(H5Awrite(attr, type, packed.data()), 0) << name;
    H5Aclose(attr);
    H5Sclose(space);
    H5Tclose(type);
  }

  // Replaces dataset `name` by one whose raw data live in the file `outside`.
  void declare_external(const std::string& name, hid_t type, const std::vector<hsize_t>& dims,
                        const std::filesystem::path& outside) {
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    EXPECT_GE(H5Pset_external(dcpl, outside.c_str(), 0, H5F_UNLIMITED), 0);
    create(name, type, dims, dcpl);
    H5Pclose(dcpl);
  }

 private:
  void create(const std::string& name, hid_t type, const std::vector<hsize_t>& dims, hid_t dcpl) {
    EXPECT_GE(H5Ldelete(id_, name.c_str(), H5P_DEFAULT), 0) << name;
    const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
    const hid_t ds = H5Dcreate2(id_, name.c_str(), type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    EXPECT_GE(ds, 0) << name;
    H5Dclose(ds);
    H5Sclose(space);
  }

  hid_t id_;
};

class DeclaredSize : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    path_ = dir_ / "plate.h5";
    core::write_package(package_, path_);
  }

  std::string file_bytes() const { return std::to_string(std::filesystem::file_size(path_)); }

  core::ScenePackage package_ = testing::make_plate_package();
  std::filesystem::path dir_, path_;
};

TEST_F(DeclaredSize, TheUnmodifiedPackageIsAccepted) {
  EXPECT_EQ(package_rejection(path_), "");
}

// 2^31 x 2^31 float32 is 2^64 bytes: Eigen's size check threw std::bad_alloc.
TEST_F(DeclaredSize, AMatrixBeyondAnyMemoryIsRefused) {
  RawFile(path_).declare("/portrait/q_u", H5T_IEEE_F32LE, {hsize_t{1} << 31, hsize_t{1} << 31});
  EXPECT_THAT(package_rejection(path_),
              AllOf(HasSubstr("plate.h5: /portrait/q_u: declares a 2147483648x2147483648 float32 dataset"),
                    HasSubstr("more than 2^64 bytes"), Not(HasSubstr("\n"))));
}

// 2^62 int32: std::vector's constructor threw std::length_error.
TEST_F(DeclaredSize, AVectorBeyondAnyMemoryIsRefused) {
  RawFile(path_).declare("/portrait/irf_start", H5T_STD_I32LE, {hsize_t{1} << 62});
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("plate.h5: /portrait/irf_start: declares a 4611686018427387904 int32 "
                        "dataset, more than 2^64 bytes"));
}

// 2^61 variable-length strings: 2^64 bytes of pointers before reading one.
TEST_F(DeclaredSize, StringsBeyondAnyMemoryAreRefused) {
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, H5T_VARIABLE);
  RawFile(path_).declare("/palette/names", type, {hsize_t{1} << 61});
  H5Tclose(type);
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("plate.h5: /palette/names: declares a 2305843009213693952 string "
                        "dataset, more than 2^64 bytes"));
}

// 9.5 GB of U_u that would fit in memory on a large machine, declared in a
// file of a few hundred kilobytes: refused without allocating it.
TEST_F(DeclaredSize, ADatasetLargerThanTheFileIsRefused) {
  const auto rows = static_cast<hsize_t>(package_.reduction.U_u.rows());
  const hsize_t cols = 9'500'000'000 / 4 / rows;
  RawFile(path_).declare("/reduction/U_u", H5T_IEEE_F32LE, {rows, cols});
  const std::uint64_t bytes = 4 * rows * cols;
  EXPECT_THAT(
      package_rejection(path_),
      HasSubstr(fmt::format("plate.h5: /reduction/U_u: declares a {}x{} float32 dataset ({} bytes) but "
                            "the file stores 0 bytes of it (expected all of it in the {}-byte file)",
                            rows, cols, bytes, file_bytes())));
}

// A handful of rows declared, none written: the data would be fill values.
TEST_F(DeclaredSize, ADatasetWithUnwrittenChunksIsRefused) {
  const auto N = static_cast<hsize_t>(package_.portrait.nodes());
  RawFile(path_).declare("/portrait/qdot_u", H5T_IEEE_F32LE, {N, 4});
  EXPECT_THAT(
      package_rejection(path_),
      HasSubstr(fmt::format("/portrait/qdot_u: declares a {}x4 float32 dataset ({} bytes) but the file "
                            "stores 0 bytes of it",
                            N, 16 * N)));
}

// A package must hold its own data: external raw data could name any file
// the server can read (and basis downloads would send it to clients).
TEST_F(DeclaredSize, RawDataInAnotherFileIsRefused) {
  const auto& q = package_.portrait.q_u;
  const auto outside = dir_ / "outside.bin";
  std::ofstream(outside, std::ios::binary)
      .write(reinterpret_cast<const char*>(q.data()), static_cast<std::streamsize>(q.size() * sizeof(float)));
  RawFile(path_).declare_external("/portrait/q_u", H5T_IEEE_F32LE,
                                  {static_cast<hsize_t>(q.rows()), static_cast<hsize_t>(q.cols())}, outside);
  EXPECT_THAT(package_rejection(path_),
              HasSubstr("plate.h5: /portrait/q_u: raw data stored outside the file"));
}

// Found while tracing a fuzzer hang in the scene attribute: the name was
// read into room for one string whatever the attribute's size, and H5Aread
// writes every element (here 3 x 64 bytes into 65: a heap overflow).
TEST_F(DeclaredSize, ASceneAttributeOfSeveralStringsIsRefused) {
  RawFile(path_).string_array_attribute("scene", {"plate", "more", "and more"}, 64);
  EXPECT_THAT(package_rejection(path_), HasSubstr("plate.h5: /@scene: expected one string, got 3"));
}

// Shapes are checked on the declared extents of every dataset before any
// data is read: the normals' wrong row count is reported, not their corrupt
// bytes (which the reader would otherwise have tried to read first).
TEST_F(DeclaredSize, ShapesAreCheckedBeforeAnyDataIsRead) {
  const auto S = static_cast<std::uint64_t>(package_.mesh.points());
  const std::vector<float> marker(3 * (S + 1), 1234.5f);
  {
    auto f = core::h5::File::open_write(path_);
    f.remove("/mesh/normals");
    f.write("/mesh/normals", marker.data(), {S + 1, 3});
  }
  std::fstream f(path_, std::ios::in | std::ios::out | std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(f)), {});
  const float probe = 1234.5f;
  const auto at = bytes.find(std::string(reinterpret_cast<const char*>(&probe), sizeof probe));
  ASSERT_NE(at, std::string::npos);
  f.seekp(static_cast<std::streamoff>(at));
  f.write("\x7f\x7f\x7f\x7f", 4);  // fails the chunk's Fletcher-32 checksum
  f.close();
  EXPECT_THAT(package_rejection(path_),
              HasSubstr(fmt::format("/mesh/normals: expected shape S x 3 = {}x3, got {}x3", S, S + 1)));
}

}  // namespace
}  // namespace phasecast
