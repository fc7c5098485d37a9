#pragma once
// Uniform grid hash over axis-aligned boxes (the broad phase of contact): the
// cell size is the mean box extent, so each box touches few cells. The cells'
// box lists live in one flat array (counted, then filled) behind an
// open-addressing table: a paper-size cloth builds several of these per
// substep, and a map of vectors spent more time allocating than testing.
// Private to the simulation section.

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <utility>
#include <vector>

namespace phasecast::precompute {

class BoxHash {
 public:
  explicit BoxHash(const std::vector<Eigen::AlignedBox3d>& boxes) : boxes_(boxes) {
    double extent = 1e-9;
    for (const auto& b : boxes) extent += b.sizes().maxCoeff() / static_cast<double>(boxes.size());
    cell_ = extent;
    size_t entries = 0;
    for (const auto& b : boxes) visit(b, [&](std::int64_t) { ++entries; });
    size_t slots = 16;
    while (slots < 2 * entries) slots *= 2;
    keys_.assign(slots, kEmpty);
    first_.assign(slots + 1, 0);
    // Count each cell's boxes, turn counts into offsets, then fill in box order
    // (so every cell lists its boxes ascending).
    for (const auto& b : boxes) visit(b, [&](std::int64_t key) { ++first_[claim(key)]; });
    size_t offset = 0;
    for (size_t s = 0; s < slots; ++s) offset += std::exchange(first_[s], offset);
    first_[slots] = offset;
    members_.resize(entries);
    std::vector<size_t> next(first_.begin(), first_.end() - 1);
    for (size_t i = 0; i < boxes.size(); ++i)
      visit(boxes[i], [&](std::int64_t key) { members_[next[find(key)]++] = static_cast<int>(i); });
  }

  // Indices of boxes overlapping `query`, sorted and unique (deterministic).
  std::vector<int> overlapping(const Eigen::AlignedBox3d& query) const {
    std::vector<int> out;
    overlapping(query, out);
    return out;
  }
  // The same into `out` (cleared first), for callers that query in a loop.
  // A box is listed only from the first cell it shares with the query, so a
  // large box is not pushed once per shared cell (sorting those repeats was a
  // fifth of a resting plant's frame); the sort and unique remain for boxes
  // repeated in a slot by colliding cell keys.
  void overlapping(const Eigen::AlignedBox3d& query, std::vector<int>& out) const {
    out.clear();
    const Cell low = cell_of(query.min());
    visit(query, [&](std::int64_t key, const Cell& cell) {
      const size_t s = find(key);
      if (s == kMissing) return;
      for (size_t k = first_[s]; k < first_[s + 1]; ++k) {
        const int i = members_[k];
        const auto& box = boxes_[static_cast<size_t>(i)];
        if (!box.intersects(query)) continue;
        const Cell own = cell_of(box.min());
        const Cell first{std::max(low[0], own[0]), std::max(low[1], own[1]), std::max(low[2], own[2])};
        if (cell == first) out.push_back(i);
      }
    });
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  }

 private:
  using Cell = std::array<std::int64_t, 3>;
  static constexpr std::int64_t kEmpty = INT64_MIN;
  static constexpr size_t kMissing = SIZE_MAX;

  // Spatial hash of integer cells; key from the three cell coordinates.
  static std::int64_t cell_key(std::int64_t i, std::int64_t j, std::int64_t k) {
    return (i * 73856093) ^ (j * 19349663) ^ (k * 83492791);
  }
  size_t home(std::int64_t key) const {
    return static_cast<size_t>(static_cast<std::uint64_t>(key) * 0x9E3779B97F4A7C15ull) & (keys_.size() - 1);
  }
  // The slot of `key`, taken if new (linear probing; the table is at most half full).
  size_t claim(std::int64_t key) {
    size_t s = home(key);
    while (keys_[s] != kEmpty && keys_[s] != key) s = (s + 1) & (keys_.size() - 1);
    keys_[s] = key;
    return s;
  }
  size_t find(std::int64_t key) const {
    for (size_t s = home(key);; s = (s + 1) & (keys_.size() - 1)) {
      if (keys_[s] == key) return s;
      if (keys_[s] == kEmpty) return kMissing;
    }
  }
  std::int64_t index(double c) const { return static_cast<std::int64_t>(std::floor(c / cell_)); }
  Cell cell_of(const Eigen::Vector3d& p) const { return {index(p.x()), index(p.y()), index(p.z())}; }
  // Calls f(key) or f(key, cell) for every cell the box touches.
  template <class F>
  void visit(const Eigen::AlignedBox3d& b, F&& f) const {
    const Cell lo = cell_of(b.min()), hi = cell_of(b.max());
    for (auto i = lo[0]; i <= hi[0]; ++i)
      for (auto j = lo[1]; j <= hi[1]; ++j)
        for (auto k = lo[2]; k <= hi[2]; ++k) {
          if constexpr (std::is_invocable_v<F, std::int64_t, const Cell&>) {
            f(cell_key(i, j, k), Cell{i, j, k});
          } else {
            f(cell_key(i, j, k));
          }
        }
  }

  const std::vector<Eigen::AlignedBox3d>& boxes_;
  double cell_ = 1;
  std::vector<std::int64_t> keys_;  // open-addressing table of cell keys
  std::vector<size_t> first_;       // per slot: its boxes are members_[first_[s], first_[s + 1])
  std::vector<int> members_;
};

}  // namespace phasecast::precompute
