#include "phasecast/precompute/sampling/palette_rules.h"

#include "phasecast/core/package.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace phasecast::precompute {
namespace {

// `words`: what the field takes besides entry names ("rest" in after, "rest, hold" in on_end).
std::string known_names(const Scene& scene, const std::string& words) {
  std::string s = words;
  for (const auto& e : scene.palette) s += (s.empty() ? "" : ", ") + e.name;
  return s;
}

int entry_named(const Scene& scene, const PaletteEntry& entry, const std::string& field,
                const std::string& name, bool with_rest, const std::string& words = "") {
  for (size_t i = 0; i < scene.palette.size(); ++i) {
    if (scene.palette[i].name == name) return static_cast<int>(i);
  }
  if (with_rest && name == "rest") return -1;
  throw SceneError(fmt::format("{}: palette entry '{}': field '{}': unknown name '{}' (expected {})",
                               scene.source.string(), entry.name, field, name,
                               known_names(scene, words.empty() && with_rest ? "rest" : words)));
}

}  // namespace

bool PaletteRules::allowed(int from, int to) const {
  return transitions(from + 1, to) != 0;
}

std::vector<int> PaletteRules::successors(int from) const {
  std::vector<int> next;
  for (int d = 0; d < size(); ++d) {
    if (allowed(from, d)) next.push_back(d);
  }
  return next;
}

bool PaletteRules::allowed_after(const std::vector<int>& history, int to) const {
  if (!allowed(history.empty() ? -1 : history.back(), to)) return false;
  core::PaletteRun run;
  for (const int e : history) run = core::extended_run(group, run, e);
  return core::within_run_limit(group, max_in_a_row, run, to);
}

int PaletteRules::reachable_frames(int entry, double at) const {
  const auto e = static_cast<size_t>(entry);
  return core::frames_of_support_motion(support_rate[e], range_min, range_max, at, frame_dt, max_frames[e]);
}

bool PaletteRules::allowed_at(const std::vector<int>& history, int to, double at) const {
  return allowed_after(history, to) && reachable_frames(to, at) >= 1;
}

double PaletteRules::advance(int entry, double at, int frames) const {
  const double moved = at + support_rate[static_cast<size_t>(entry)] * frames * frame_dt;
  return range_max > range_min ? std::clamp(moved, range_min, range_max) : moved;
}

PaletteRules make_palette_rules(const Scene& scene) {
  const int D = static_cast<int>(scene.palette.size());
  const double dt = scene.simulation.frame_dt;
  PaletteRules rules;
  rules.transitions = MatrixXbR::Zero(D + 1, D);
  for (int d = 0; d < D; ++d) {
    const auto& e = scene.palette[static_cast<size_t>(d)];
    if (e.after.empty()) rules.transitions.col(d).setOnes();
    for (const auto& name : e.after) rules.transitions(entry_named(scene, e, "after", name, true) + 1, d) = 1;
    // T in (t_min, t_max) rounded to whole frames, at least one frame.
    const int lo = std::max(1, static_cast<int>(std::ceil(e.t_min / dt - 1e-9)));
    const int hi = static_cast<int>(std::floor(e.t_max / dt + 1e-9));
    if (hi < lo) {
      throw SceneError(
          fmt::format("{}: palette entry '{}': field 't_max': expected at least one frame ({} s) "
                      "above t_min, got {} s",
                      scene.source.string(), e.name, dt, e.t_max));
    }
    rules.min_frames.push_back(lo);
    rules.max_frames.push_back(hi);
    int g = 0;
    while (g < d && scene.palette[static_cast<size_t>(g)].group != e.group) ++g;
    rules.group.push_back(g == d ? d : rules.group[static_cast<size_t>(g)]);
    rules.max_in_a_row.push_back(e.max_in_a_row);
    rules.support_rate.push_back(e.alpha_forcing.dot(scene.support.axis));
  }
  rules.range_min = scene.support.range_min;
  rules.range_max = scene.support.range_max;
  rules.frame_dt = dt;
  for (int d = 0; d < D; ++d) {
    const auto& e = scene.palette[static_cast<size_t>(d)];
    if (e.on_end == "rest") {
      rules.on_end.push_back(core::kEndRest);
    } else if (e.on_end == "hold") {
      rules.on_end.push_back(core::kEndHold);
    } else {
      const int next = entry_named(scene, e, "on_end", e.on_end, false, "rest, hold");
      if (!rules.allowed(d, next)) {
        throw SceneError(
            fmt::format("{}: palette entry '{}': field 'on_end': follow-up '{}' must list '{}' in "
                        "its 'after'",
                        scene.source.string(), e.name, e.on_end, e.name));
      }
      rules.on_end.push_back(next);
    }
  }
  return rules;
}

}  // namespace phasecast::precompute
