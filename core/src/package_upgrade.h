#pragma once
// Packages written in an older format version, read into today's structures.
// This is the one place that knows the older layouts (docs/package-format.md,
// "Older versions"); everything else reads and writes today's.

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/package.h"

#include <optional>

namespace phasecast::core {

// The oldest format_version read_package() reads.
inline constexpr int kOldestFormatVersion = 1;

// The held-out figures of a package in format `version` (older than
// kFormatVersion), or none when it holds none. Checks the old layout's
// extents before it reads anything and fails through `r` with one line.
std::optional<HeldOutFigures> upgrade_held_out(const h5::Reader& r, int version);

}  // namespace phasecast::core
