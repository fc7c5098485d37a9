#pragma once
// Where many instances stand in one view when the default grid
// (grid_placements) is not wanted: a layout file, JSON,
//   {"placements": [{"translate": [x, y, z], "rotate_y_deg": a}, ...]}
// one entry per instance in the order the renderer draws them (id order for
// a server's instances, copy order for --count). Both fields are optional
// (no move, no turn); the turn is about the up axis y, so instances stand on
// the same floor (docs/client.md).

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace phasecast::client {

// Instance frame -> world transforms, one per entry. Throws
// std::invalid_argument with one line naming the file, the entry and what
// was expected (unreadable file, not JSON, unknown key, non-finite value).
std::vector<Eigen::Matrix4f> read_layout(const std::filesystem::path& file);

// The first `count` placements of the layout; throws std::invalid_argument
// naming the file when it places fewer.
std::vector<Eigen::Matrix4f> layout_placements(const std::vector<Eigen::Matrix4f>& layout,
                                               const std::filesystem::path& file, int count);

}  // namespace phasecast::client
