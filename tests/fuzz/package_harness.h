#pragma once
// Package-reader fuzzing: mutated package files go through core::read_package
// and validate_package (PackageHarness), and the mutations know where HDF5
// keeps its checksummed metadata (PackageMutator), so that they reach the
// dataspaces, datatypes, layouts and attributes behind the checksums.

#include "fuzz_support.h"
#include "phasecast/core/package.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace phasecast::fuzz {

struct PackageVerdict {
  std::string violation;  // empty unless an invariant broke
  std::string kind;       // "accepted", or "refused <error line without numbers>"
};

class PackageHarness {
 public:
  // Inputs are written to `work_file` and read back from it.
  explicit PackageHarness(std::filesystem::path work_file) : path_(std::move(work_file)) {}

  // Every outcome must be a package that validates and can be served (an
  // engine ticks through each palette entry, the basis parts have their
  // documented sizes) or one PackageError line naming the file; nothing else
  // may escape and no HDF5 object may stay open.
  PackageVerdict run(std::string_view bytes);

 private:
  std::string serve(const core::ScenePackage& package) const;
  std::filesystem::path path_;
};

// A checksummed HDF5 metadata block: the version 2/3 superblock, an object
// header ("OHDR", version 2) or one of its continuation chunks ("OCHK").
// Its checksum (Jenkins' lookup3, as HDF5 computes it) is the 4 bytes at `end`.
struct HeaderMessage {
  int type = 0;  // 0x01 dataspace, 0x03 datatype, 0x08 layout, 0x0b filters, 0x0c attribute, ...
  std::size_t begin = 0;
  std::size_t end = 0;  // of its body
};

struct MetadataBlock {
  std::size_t begin = 0;
  std::size_t end = 0;
  std::vector<HeaderMessage> messages;  // for aimed mutations (none in the superblock)
};

// Recomputes and stores `block`'s checksum after its bytes were changed.
void store_checksum(Bytes& file, const MetadataBlock& block);

// The blocks of `file` whose stored checksum verifies.
std::vector<MetadataBlock> metadata_blocks(const Bytes& file);
std::uint32_t lookup3(const char* data, std::size_t size);

class PackageMutator {
 public:
  explicit PackageMutator(Random& random) : random_(random), bytes_(random) {}
  // `parent` mutated: inside a metadata block with its checksum repaired, or
  // anywhere byte-wise (bulk data, B-trees and heaps carry no checksum of
  // their own beyond Fletcher-32 on chunks), or resized and spliced.
  Bytes mutate(const Bytes& parent, const Bytes& other);

 private:
  bool mutate_metadata(Bytes& data);

  Random& random_;
  ByteMutator bytes_;
};

}  // namespace phasecast::fuzz
