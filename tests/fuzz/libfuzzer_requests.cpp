// libFuzzer entry point over RequestHarness (clang, -DPHASECAST_LIBFUZZER=ON;
// docs/fuzzing.md). PHASECAST_FUZZ_PACKAGE names the package to serve.

#include "request_harness.h"

#include <cstdio>
#include <cstdlib>
#include <memory>

namespace {

std::unique_ptr<phasecast::fuzz::RequestHarness> g_harness;

}  // namespace

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* package = std::getenv("PHASECAST_FUZZ_PACKAGE");
  if (!package) {
    std::fprintf(stderr, "set PHASECAST_FUZZ_PACKAGE to a tiny package (tests/data/packages/plant_pot.h5)\n");
    std::exit(2);
  }
  const auto dir = std::filesystem::temp_directory_path() / "phasecast-libfuzzer-requests";
  std::filesystem::create_directories(dir);
  g_harness =
      std::make_unique<phasecast::fuzz::RequestHarness>(std::vector<std::filesystem::path>{package}, dir);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const auto v = g_harness->run(bytes);
  if (!v.violation.empty()) {
    std::fprintf(stderr, "invariant broken: %s\n", v.violation.c_str());
    std::abort();  // libFuzzer saves the input as a crash
  }
  // Interleave ticks, chosen by the input so that runs stay reproducible.
  if (size > 0 && data[size - 1] % 8 == 0) {
    if (const auto t = g_harness->tick(); !t.empty()) {
      std::fprintf(stderr, "invariant broken by a tick: %s\n", t.c_str());
      std::abort();
    }
  }
  return 0;
}

// Half the time the schema-aware mutations, half libFuzzer's own.
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
  phasecast::fuzz::Random random(seed);
  if (random.one_in(2)) return LLVMFuzzerMutate(data, size, max_size);
  phasecast::fuzz::RequestMutator mutator(random, *g_harness);
  const phasecast::fuzz::Bytes parent(reinterpret_cast<const char*>(data), size);
  const auto out = mutator.mutate(parent, parent);
  const size_t n = std::min(out.size(), max_size);
  std::copy_n(out.data(), n, data);
  return n;
}
