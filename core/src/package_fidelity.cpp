#include "package_fidelity.h"

#include <array>
#include <cstdint>
#include <vector>

namespace phasecast::core {
namespace {

using h5::Dtype;

std::array<std::int32_t*, 6> counts_of(PlaybackFidelity& p) {
  return {&p.schedules, &p.items, &p.moving, &p.moving_within, &p.switches, &p.switches_within};
}

std::array<std::int32_t, 6> counts_of(const PlaybackFidelity& p) {
  return {p.schedules, p.items, p.moving, p.moving_within, p.switches, p.switches_within};
}

}  // namespace

void add_fidelity_datasets(const h5::Reader& r, PackageShapes& s) {
  const auto add = [&](const char* name, Dtype dtype) {
    if (r.file().exists(name)) s[name] = r.require(name, dtype, 1).dims;
  };
  for (const char* name : kFidelityCounts) add(name, Dtype::i32);
  add(kFidelitySeed, Dtype::f64);
  for (const char* name : kFidelityNrmse) add(name, Dtype::f32);
  add(kFidelityTarget, Dtype::f32);
  for (const char* name : kFidelityAdaptiveCounts) add(name, Dtype::i32);
  add(kFidelityTargetMet, Dtype::u8);
}

void add_fidelity_shapes(const PlaybackFidelity& p, PackageShapes& s) {
  for (const char* name : kFidelityCounts) s[name] = {1};
  s[kFidelitySeed] = {1};
  for (const char* name : kFidelityNrmse) s[name] = {1};
  if (p.target_median_nrmse) {
    s[kFidelityTarget] = {1};
    for (const char* name : kFidelityAdaptiveCounts) s[name] = {1};
    s[kFidelityTargetMet] = {1};
  }
}

std::optional<PlaybackFidelity> read_fidelity(const h5::Reader& r) {
  if (!r.file().exists(kFidelityGroup)) return std::nullopt;
  PlaybackFidelity p;
  const auto counts = counts_of(p);
  for (size_t i = 0; i < counts.size(); ++i) *counts[i] = r.vector<std::int32_t>(kFidelityCounts[i]).at(0);
  p.seed = r.column<double>(kFidelitySeed, 1)[0];
  p.median_nrmse = r.column<float>(kFidelityNrmse[0], 1)[0];
  p.p90_nrmse = r.column<float>(kFidelityNrmse[1], 1)[0];
  if (r.file().exists(kFidelityTarget)) {
    p.target_median_nrmse = r.column<float>(kFidelityTarget, 1)[0];
    p.sampled_irfs = r.vector<std::int32_t>(kFidelityAdaptiveCounts[0]).at(0);
    p.rounds = r.vector<std::int32_t>(kFidelityAdaptiveCounts[1]).at(0);
    p.target_met = r.vector<std::uint8_t>(kFidelityTargetMet).at(0) != 0;
  }
  return p;
}

void write_fidelity(h5::File& f, const PlaybackFidelity& p) {
  const auto counts = counts_of(p);
  for (size_t i = 0; i < counts.size(); ++i)
    f.write(kFidelityCounts[i], std::vector<std::int32_t>{counts[i]});
  f.write(kFidelitySeed, std::vector<double>{p.seed});
  f.write(kFidelityNrmse[0], std::vector<float>{p.median_nrmse});
  f.write(kFidelityNrmse[1], std::vector<float>{p.p90_nrmse});
  if (!p.target_median_nrmse) return;
  f.write(kFidelityTarget, std::vector<float>{*p.target_median_nrmse});
  f.write(kFidelityAdaptiveCounts[0], std::vector<std::int32_t>{p.sampled_irfs});
  f.write(kFidelityAdaptiveCounts[1], std::vector<std::int32_t>{p.rounds});
  f.write(kFidelityTargetMet, std::vector<std::uint8_t>{p.target_met ? std::uint8_t{1} : std::uint8_t{0}});
}

}  // namespace phasecast::core
