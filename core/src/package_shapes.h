#pragma once
// The extents of a package's datasets and the shape rules of
// docs/package-format.md, in one place for two callers: the reader checks the
// extents the file declares before it allocates anything for the data
// (issue 18), and validate_package() checks an in-memory package, so that a
// writer and a reader can never disagree about a shape.

#include "phasecast/core/package.h"

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace phasecast::core {

using Extent = std::vector<std::uint64_t>;

// Dataset path -> extent. Absent optional datasets (/portrait/support, the
// appearance block) are absent here too; /palette/group and
// /palette/max_in_a_row are D long and /portrait/q_a is N x 0 when the
// package has none, as the reader fills them in.
using PackageShapes = std::map<std::string, Extent>;

// The extents write_package() would give `package`'s datasets.
PackageShapes shapes_of(const ScenePackage& package);

// Throws PackageError "<source>: <dataset>: expected ..., got ..." for the
// first extent that breaks a rule (S, F, D, k, N, r_u, r_a, N_a agreeing).
void check_shapes(const PackageShapes& shapes, const std::string& source);

}  // namespace phasecast::core
