#pragma once
// The D x 11 row form of SupportKinematics used by /palette/kinematics in
// packages and orbit stores (docs/package-format.md gives the columns).

#include "phasecast/core/package.h"

#include <vector>

namespace phasecast::core {

inline constexpr const char* kKinematicsColumnNames =
    "axis_x,axis_y,axis_z,pivot_x,pivot_y,pivot_z,rotational,rate,range_min,range_max,pulse_tau";

// One row per entry, kKinematicsColumns columns.
MatrixXfR kinematics_to_rows(const std::vector<SupportKinematics>& kinematics);

// The inverse; `rows` must have kKinematicsColumns columns.
std::vector<SupportKinematics> kinematics_from_rows(const MatrixXfR& rows);

}  // namespace phasecast::core
