#pragma once
// /fidelity/ of a package (docs/package-format.md): playback against the full
// simulation, each figure a dataset of one value.

#include "package_shapes.h"
#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/package.h"

#include <optional>

namespace phasecast::core {

inline constexpr const char* kFidelityGroup = "/fidelity";
// Required in the group: the counts (i32), the seed (f64), the NRMSE figures (f32).
inline constexpr const char* kFidelityCounts[] = {"/fidelity/schedules", "/fidelity/items",
                                                  "/fidelity/moving",    "/fidelity/moving_within",
                                                  "/fidelity/switches",  "/fidelity/switches_within"};
inline constexpr const char* kFidelitySeed = "/fidelity/seed";
inline constexpr const char* kFidelityNrmse[] = {"/fidelity/median_nrmse", "/fidelity/p90_nrmse"};
// Together or not at all: adaptive sampling's target (f32), IRFs and rounds (i32), whether it was met (u8).
inline constexpr const char* kFidelityTarget = "/fidelity/target_median_nrmse";
inline constexpr const char* kFidelityAdaptiveCounts[] = {"/fidelity/sampled_irfs", "/fidelity/rounds"};
inline constexpr const char* kFidelityTargetMet = "/fidelity/target_met";

// The extents of the /fidelity datasets the file holds, each checked against what it stores.
void add_fidelity_datasets(const h5::Reader& r, PackageShapes& shapes);
// The extents write_package() gives `fidelity`'s datasets.
void add_fidelity_shapes(const PlaybackFidelity& fidelity, PackageShapes& shapes);
// After check_shapes(): the figures (absent: none measured).
std::optional<PlaybackFidelity> read_fidelity(const h5::Reader& r);
void write_fidelity(h5::File& f, const PlaybackFidelity& fidelity);

}  // namespace phasecast::core
