// libFuzzer entry point over PackageHarness (clang, -DPHASECAST_LIBFUZZER=ON;
// docs/fuzzing.md). Seed the corpus with the files phasecast-fuzz-package
// writes (seed-*.h5) and the packages of tests/data/packages.

#include "package_harness.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>

namespace {

std::unique_ptr<phasecast::fuzz::PackageHarness> g_harness;

}  // namespace

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // One work file per process: libFuzzer's -jobs run several at once.
  const auto dir = std::filesystem::temp_directory_path() / "phasecast-libfuzzer-package";
  std::filesystem::create_directories(dir);
  g_harness = std::make_unique<phasecast::fuzz::PackageHarness>(
      dir / ("input-" + std::to_string(::getpid()) + ".h5"));
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto v = g_harness->run(std::string_view(reinterpret_cast<const char*>(data), size));
  if (!v.violation.empty()) {
    std::fprintf(stderr, "invariant broken: %s\n", v.violation.c_str());
    std::abort();  // libFuzzer saves the input as a crash
  }
  return 0;
}

// Half the time the HDF5-aware mutations (checksums repaired), half libFuzzer's own.
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
  phasecast::fuzz::Random random(seed);
  if (random.one_in(2)) return LLVMFuzzerMutate(data, size, max_size);
  phasecast::fuzz::PackageMutator mutator(random);
  const phasecast::fuzz::Bytes parent(reinterpret_cast<const char*>(data), size);
  const auto out = mutator.mutate(parent, parent);
  const size_t n = std::min(out.size(), max_size);
  std::copy_n(out.data(), n, data);
  return n;
}
