#include "phasecast/core/hash.h"

#include <fmt/format.h>

#include <fstream>
#include <stdexcept>
#include <vector>

namespace phasecast::core {

std::uint64_t content_hash(std::span<const std::byte> bytes, std::uint64_t seed) {
  std::uint64_t h = seed;
  for (std::byte b : bytes) {
    h ^= static_cast<std::uint64_t>(b);
    h *= 0x100000001b3ull;
  }
  return h;
}

std::uint64_t file_content_hash(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open for hashing", path.string()));
  std::uint64_t h = 0xcbf29ce484222325ull;
  std::vector<char> buffer(1 << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const auto n = static_cast<std::size_t>(in.gcount());
    h = content_hash(std::as_bytes(std::span(buffer.data(), n)), h);
  }
  return h;
}

}  // namespace phasecast::core
