#pragma once
// Uniform grid hash over axis-aligned boxes (the broad phase of contact): the
// cell size is the mean box extent, so each box touches few cells. Private to
// the simulation section.

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace phasecast::precompute {

class BoxHash {
 public:
  explicit BoxHash(const std::vector<Eigen::AlignedBox3d>& boxes) : boxes_(boxes) {
    double extent = 1e-9;
    for (const auto& b : boxes) extent += b.sizes().maxCoeff() / static_cast<double>(boxes.size());
    cell_ = extent;
    for (size_t i = 0; i < boxes.size(); ++i) {
      visit(boxes[i], [&](std::int64_t key) { cells_[key].push_back(static_cast<int>(i)); });
    }
  }

  // Indices of boxes overlapping `query`, sorted and unique (deterministic).
  std::vector<int> overlapping(const Eigen::AlignedBox3d& query) const {
    std::vector<int> out;
    visit(query, [&](std::int64_t key) {
      const auto it = cells_.find(key);
      if (it == cells_.end()) return;
      for (int i : it->second) {
        if (boxes_[static_cast<size_t>(i)].intersects(query)) out.push_back(i);
      }
    });
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
  }

 private:
  // Spatial hash of integer cells; key from the three cell coordinates.
  static std::int64_t cell_key(std::int64_t i, std::int64_t j, std::int64_t k) {
    return (i * 73856093) ^ (j * 19349663) ^ (k * 83492791);
  }
  template <class F>
  void visit(const Eigen::AlignedBox3d& b, F&& f) const {
    const auto index = [&](double c) { return static_cast<std::int64_t>(std::floor(c / cell_)); };
    for (auto i = index(b.min().x()); i <= index(b.max().x()); ++i)
      for (auto j = index(b.min().y()); j <= index(b.max().y()); ++j)
        for (auto k = index(b.min().z()); k <= index(b.max().z()); ++k) f(cell_key(i, j, k));
  }
  const std::vector<Eigen::AlignedBox3d>& boxes_;
  double cell_ = 1;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

}  // namespace phasecast::precompute
