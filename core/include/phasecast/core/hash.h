#pragma once
// Content hashes that name a package in recordings and let a reconnecting
// client check that its downloaded bases are still current. FNV-1a 64: an
// identity check, not a security measure.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>

namespace phasecast::core {

std::uint64_t content_hash(std::span<const std::byte> bytes, std::uint64_t seed = 0xcbf29ce484222325ull);

// Hash of a whole file's bytes. Throws std::runtime_error if it cannot be read.
std::uint64_t file_content_hash(const std::filesystem::path& path);

}  // namespace phasecast::core
