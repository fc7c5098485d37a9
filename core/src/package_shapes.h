#pragma once
// The extents of a package's datasets and the shape rules of
// docs/package-format.md, in one place for two callers: the reader checks the
// extents the file declares before it allocates anything for the data
// (issue 18), and validate_package() checks an in-memory package, so that a
// writer and a reader can never disagree about a shape.

#include "phasecast/core/package.h"

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::core {

using Extent = std::vector<std::uint64_t>;

// Dataset path -> extent. Absent optional datasets (/portrait/support, the
// appearance block) are absent here too; /palette/group and
// /palette/max_in_a_row are D long and /portrait/q_a is N x 0 when the
// package has none, as the reader fills them in.
using PackageShapes = std::map<std::string, Extent>;

// The held-out figures' datasets, /appearance/held_out/<name>: one value
// each, two (10th and 90th percentile) for a spread.
struct HeldOutFigure {
  const char* name;
  float HeldOutFigures::*member;
};
struct OptionalHeldOutFigure {
  const char* name;
  std::optional<float> HeldOutFigures::*member;
};
struct HeldOutSpread {
  const char* name;
  std::optional<Percentiles> HeldOutFigures::*member;
};
inline constexpr HeldOutFigure kHeldOutFigures[] = {
    {"/appearance/held_out/total", &HeldOutFigures::total},
    {"/appearance/held_out/truncation", &HeldOutFigures::truncation},
    {"/appearance/held_out/interpolation", &HeldOutFigures::interpolation},
    {"/appearance/held_out/of_transfer", &HeldOutFigures::of_transfer},
};
inline constexpr OptionalHeldOutFigure kOptionalHeldOutFigures[] = {
    {"/appearance/held_out/l2_total", &HeldOutFigures::l2_total},
    {"/appearance/held_out/l2_truncation", &HeldOutFigures::l2_truncation},
    {"/appearance/held_out/clusters_l2_truncation", &HeldOutFigures::clusters_l2_truncation},
    {"/appearance/held_out/l2_floor", &HeldOutFigures::l2_floor},
    {"/appearance/held_out/of_variation", &HeldOutFigures::of_variation},
    {"/appearance/held_out/l2_of_variation", &HeldOutFigures::l2_of_variation},
    {"/appearance/held_out/l2_floor_of_variation", &HeldOutFigures::l2_floor_of_variation},
};
inline constexpr HeldOutSpread kHeldOutSpreads[] = {
    {"/appearance/held_out/l2_total_spread", &HeldOutFigures::l2_total_spread},
    {"/appearance/held_out/l2_truncation_spread", &HeldOutFigures::l2_truncation_spread},
    {"/appearance/held_out/l2_of_variation_spread", &HeldOutFigures::l2_of_variation_spread},
};
inline constexpr const char* kHeldOutNodes = "/appearance/held_out/nodes";
inline constexpr const char* kHeldOutCurve = "/appearance/held_out/truncation_curve";

// The extents write_package() would give these figures' datasets.
void add_held_out_shapes(const HeldOutFigures& figures, PackageShapes& shapes);

// The extents write_package() would give `package`'s datasets.
PackageShapes shapes_of(const ScenePackage& package);

// Throws PackageError "<source>: <dataset>: expected ..., got ..." for the
// first extent that breaks a rule (S, F, D, k, N, r_u, r_a, N_a agreeing).
void check_shapes(const PackageShapes& shapes, const std::string& source);

}  // namespace phasecast::core
