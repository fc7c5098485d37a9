#pragma once
// Palette rules (§3.3): which entry may follow which, how long the sampler may
// run an IRF of each entry, and what happens when an IRF ends. Built from the
// scene's [[palette]] fields `after`, `t_min`, `t_max`, `on_end` (docs/sampling.md).

#include "phasecast/core/eigen_types.h"
#include "phasecast/precompute/simulation/scene.h"

#include <cstdint>
#include <vector>

namespace phasecast::precompute {

struct PaletteRules {
  MatrixXbR transitions;             // (D+1) x D: row 0 from rest, row i+1 after entry i (package layout)
  std::vector<std::int32_t> on_end;  // D: core::kEndRest, core::kEndHold or a follow-up entry
  std::vector<int> min_frames;       // D: shortest IRF in frames (>= 1)
  std::vector<int> max_frames;       // D: longest IRF in frames (>= min_frames)
  std::vector<std::int32_t> group;   // D: group index (entries named alike share one)
  std::vector<std::int32_t> max_in_a_row;  // D: at most this many IRFs of the entry's group in a row (0: any)
  // The support's range (§3.5: "the cloth's door has a 90 degree range of
  // motion, so IRFs with nonzero omega need be at most 90/|omega| s"). The
  // support coordinate (rad or m along the axis) is advanced kinematically, so
  // the draws stay a pure function of the chain's entries and lengths.
  std::vector<double> support_rate;  // D: held support velocity along the axis (alpha_F . axis)
  double range_min = 0;              // range_min == range_max: unlimited
  double range_max = 0;
  double frame_dt = 0;

  int size() const { return static_cast<int>(on_end.size()); }
  // Whether entry `to` may follow entry `from` (-1: from rest).
  bool allowed(int from, int to) const;
  // The entries that may follow `from` (-1: from rest), in palette order.
  std::vector<int> successors(int from) const;
  // Whether entry `to` may follow `history` (the chain's entries since it last
  // left rest, oldest first): allowed after its last entry and within max_in_a_row.
  bool allowed_after(const std::vector<int>& history, int to) const;
  // The longest IRF of `entry`, in frames, that the range allows from support
  // coordinate `at` (max_frames[entry] when unlimited or when the entry holds
  // the support still); 0 when the entry cannot move the support at all.
  int reachable_frames(int entry, double at) const;
  // allowed_after(history, to), and `to` can move the support from `at`.
  bool allowed_at(const std::vector<int>& history, int to, double at) const;
  // The support coordinate after `frames` frames of `entry` from `at`.
  double advance(int entry, double at, int frames) const;
};

// Checks the names in `after` and `on_end` against the palette and that a
// follow-up is allowed after its entry; throws SceneError naming the scene
// file, the entry and the field.
PaletteRules make_palette_rules(const Scene& scene);

}  // namespace phasecast::precompute
