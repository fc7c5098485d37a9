// What the fuzzers found, kept as tests, and checks of the fuzzers' own
// HDF5 knowledge (a mutator that mis-computes checksums would only ever
// exercise the checksum failure path).

#include "package_harness.h"
#include "phasecast/core/package.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/resource.h>

namespace phasecast {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

constexpr int kLayoutMessage = 0x08;
constexpr int kAttributeMessage = 0x0c;
constexpr char kChunkedClass = 2;

// Jenkins' own test vectors for hashlittle(key, length, 0) (lookup3.c, driver5).
TEST(Lookup3, MatchesTheReferenceVectors) {
  EXPECT_EQ(fuzz::lookup3("", 0), 0xdeadbeefu);
  EXPECT_EQ(fuzz::lookup3("Four score and seven years ago", 30), 0x17770551u);
}

class CraftedPackage : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    path_ = dir_ / "plate.h5";
    core::write_package(testing::make_plate_package(), path_);
    file_ = fuzz::read_file(path_);
  }

  // Applies `edit` to the first header message that `matches`, repairs that
  // block's checksum and writes the file; false if no message matched.
  template <class Match, class Edit>
  bool craft_first(Match matches, Edit edit) {
    for (const auto& block : fuzz::metadata_blocks(file_)) {
      for (const auto& m : block.messages) {
        if (!matches(m)) continue;
        edit(m);
        fuzz::store_checksum(file_, block);
        fuzz::write_file(path_, file_);
        return true;
      }
    }
    return false;
  }

  std::filesystem::path dir_, path_;
  fuzz::Bytes file_;
};

// Every dataset has an object header with a verified checksum: the mutator
// can reach (and repair) all of them.
TEST_F(CraftedPackage, EveryObjectHeaderIsFoundAndVerifies) {
  int layouts = 0;
  for (const auto& block : fuzz::metadata_blocks(file_)) {
    for (const auto& m : block.messages) layouts += m.type == kLayoutMessage ? 1 : 0;
  }
  EXPECT_GE(layouts, 30);  // the plate package has 33 datasets
}

// Found by phasecast-fuzz-package (seed 1, input #216): the chunked layout
// message of a 1-D dataset (dimensionality 2: rank + 1) set to
// dimensionality 0, checksum repaired. libhdf5 1.10.8 divides by zero in
// H5D__chunk_set_info (SIGFPE) when the dataset is opened; the reader must
// answer with one PackageError line instead.
TEST_F(CraftedPackage, ChunkedLayoutOfDimensionalityZeroIsRefusedNotACrash) {
  ASSERT_TRUE(craft_first(
      [&](const auto& m) {
        return m.type == kLayoutMessage && file_[m.begin + 1] == kChunkedClass && file_[m.begin + 2] == 2;
      },
      [&](const auto& m) { file_[m.begin + 2] = 0; }));  // dimensionality
  try {
    core::read_package(path_);
    FAIL() << "a package with a zero-dimensional chunk layout was accepted";
  } catch (const core::PackageError& e) {
    // Today's message is "...: reading it crashed the checking process
    // (Floating point exception; ...)"; a libhdf5 that refuses the layout
    // itself is as good.
    EXPECT_THAT(e.what(), StartsWith(path_.string() + ": "));
    EXPECT_THAT(e.what(), Not(HasSubstr("\n")));
  }
}

// Found by phasecast-fuzz-package under AddressSanitizer (seed 4, input
// #1731, a hang): the sequence length of the variable-length "scene"
// attribute set to 2^32 - 1, checksum repaired. libhdf5 allocates and
// clears a 4 GB conversion buffer before it reads the 5 real bytes, in the
// checking child and again in the caller (10 s and 8 GB here), and then
// accepts the file. The child's memory limit turns that into a refusal.
TEST_F(CraftedPackage, AHugeStringLengthIsRefusedWithoutAHugeAllocation) {
  ASSERT_TRUE(craft_first(
      [&](const auto& m) {
        return m.type == kAttributeMessage &&
               file_.substr(m.begin, m.end - m.begin).find(std::string("scene", 6)) != std::string::npos;
      },
      // The attribute's data closes the message: sequence length (4 bytes), heap address, index.
      [&](const auto& m) { file_.replace(m.end - 16, 4, "\xff\xff\xff\xff"); }));
  try {
    core::read_package(path_);
    FAIL() << "a package whose scene name claims 4 GB was accepted";
  } catch (const core::PackageError& e) {
    // "...: /@scene: cannot read attribute"; under AddressSanitizer, whose
    // failed malloc ends the child, "...: reading it crashed the checking process".
    EXPECT_THAT(e.what(), StartsWith(path_.string() + ": "));
  }
  rusage children{};
  getrusage(RUSAGE_CHILDREN, &children);
  EXPECT_LT(children.ru_maxrss, 1 << 20) << "KiB: the reading child grew to a gigabyte or more";
}

}  // namespace
}  // namespace phasecast
