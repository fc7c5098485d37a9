#include "phasecast/precompute/simulation/tet_quality.h"

#include <Eigen/Dense>

namespace phasecast::precompute {

TetSummary summarize_tets(
    const DeformableModel& model,
    const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& positions) {
  TetSummary s;
  s.frames = static_cast<int>(positions.rows());
  for (Eigen::Index f = 0; f < positions.rows(); ++f) {
    const auto x = [&](int v) { return positions.row(f).segment<3>(3 * v).transpose().cast<double>(); };
    bool inverted = false;
    for (size_t t = 0; t < model.tets.size(); ++t) {
      const auto& e = model.tets[t];
      Eigen::Matrix3d Ds;  // deformed edge matrix; F = Ds Dm^-1
      Ds << x(e.v[1]) - x(e.v[0]), x(e.v[2]) - x(e.v[0]), x(e.v[3]) - x(e.v[0]);
      const double J = (Ds * e.Dm_inv).determinant();
      inverted = inverted || J <= 0;
      if (J < s.least_j) {
        s.least_j = J;
        s.least_frame = static_cast<int>(f);
        s.least_tet = static_cast<int>(t);
      }
    }
    s.frames_inverted += inverted ? 1 : 0;
  }
  return s;
}

}  // namespace phasecast::precompute
