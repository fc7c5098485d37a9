// Version 1 stored the held-out figures by position: /appearance/held_out_error
// held 4, 6, 7, 8 or 11 floats (each length a set of figures added in turn),
// /appearance/held_out_spread 4 or 6 percentiles, beside
// /appearance/held_out_nodes and /appearance/held_out_truncation_curve.

#include "package_upgrade.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace phasecast::core {
namespace {

using h5::Dtype;

constexpr const char* kV1Nodes = "/appearance/held_out_nodes";
constexpr const char* kV1Error = "/appearance/held_out_error";
constexpr const char* kV1Spread = "/appearance/held_out_spread";
constexpr const char* kV1Curve = "/appearance/held_out_truncation_curve";

// The figures of held_out_error by position (the first four always there).
void assign_v1_figures(const VectorXf& e, HeldOutFigures& h) {
  h.total = e[0];
  h.truncation = e[1];
  h.interpolation = e[2];
  h.of_transfer = e[3];
  if (e.size() >= 6) {
    h.l2_total = e[4];
    h.l2_truncation = e[5];
  }
  if (e.size() >= 7) h.clusters_l2_truncation = e[6];
  if (e.size() >= 8) h.l2_floor = e[7];
  if (e.size() >= 11) {
    h.of_variation = e[8];
    h.l2_of_variation = e[9];
    h.l2_floor_of_variation = e[10];
  }
}

// The percentile pairs of held_out_spread by position.
void assign_v1_spread(const VectorXf& s, HeldOutFigures& h) {
  h.l2_total_spread = Percentiles{s[0], s[1]};
  h.l2_truncation_spread = Percentiles{s[2], s[3]};
  if (s.size() >= 6) h.l2_of_variation_spread = Percentiles{s[4], s[5]};
}

// The values version 1 held, checked under its own names: a finite error >=
// 0 each, nodes among the portrait's, a curve of as many directions as the
// clusters may resolve (today's rules, so that no error names a dataset the
// file does not have).
void check_v1_values(const h5::Reader& r, const char* name, const VectorXf& values) {
  for (Eigen::Index i = 0; i < values.size(); ++i)
    if (!(values[i] >= 0 && std::isfinite(values[i])))
      r.fail(name, fmt::format("expected finite errors >= 0, got {} at {}", values[i], i));
}

void check_v1_nodes(const h5::Reader& r, const std::vector<std::int32_t>& nodes) {
  const auto N = r.require("/portrait/q_u", Dtype::f32, 2).dims[0];
  for (size_t i = 0; i < nodes.size(); ++i)
    if (nodes[i] < 0 || static_cast<std::uint64_t>(nodes[i]) >= N)
      r.fail(kV1Nodes, fmt::format("expected state nodes in [0, {}), got {} at {}", N, nodes[i], i));
}

void check_v1_curve_length(const h5::Reader& r, std::uint64_t K) {
  const auto r_a = std::max<std::uint64_t>(r.require("/appearance/U_a", Dtype::f32, 2).dims[1], 1);
  const auto Na = r.require("/appearance/cluster_nodes", Dtype::i32, 1).dims[0];
  if (K < r_a || K + 1 > Na)
    r.fail(kV1Curve,
           fmt::format("expected at least r_a = {} and at most N_a - 1 = {} values, got {}", r_a, Na - 1, K));
}

std::optional<HeldOutFigures> upgrade_v1_held_out(const h5::Reader& r) {
  const auto exists = [&r](const char* name) { return r.file().exists(name); };
  if (!exists(kV1Error)) {
    for (const char* name : {kV1Spread, kV1Curve})
      if (exists(name)) r.fail(name, fmt::format("expected {} beside it", kV1Error));
    return std::nullopt;
  }
  const auto figures = r.require(kV1Error, Dtype::f32, 1).dims[0];
  if (figures != 4 && figures != 6 && figures != 7 && figures != 8 && figures != 11)
    r.fail(kV1Error, fmt::format("expected 4, 6, 7, 8 or 11 figures (format_version 1), got {}", figures));
  if (!exists(kV1Nodes)) r.fail(kV1Nodes, fmt::format("expected the nodes of {}", kV1Error));
  HeldOutFigures h;
  h.nodes = r.vector<std::int32_t>(kV1Nodes);
  check_v1_nodes(r, h.nodes);
  const VectorXf figures_read = r.column<float>(kV1Error);
  check_v1_values(r, kV1Error, figures_read);
  assign_v1_figures(figures_read, h);
  if (exists(kV1Spread)) {
    const auto values = r.require(kV1Spread, Dtype::f32, 1).dims[0];
    if (values != 4 && values != 6)
      r.fail(kV1Spread, fmt::format("expected 4 or 6 percentiles (format_version 1), got {}", values));
    const VectorXf spread = r.column<float>(kV1Spread);
    check_v1_values(r, kV1Spread, spread);
    assign_v1_spread(spread, h);
  }
  if (exists(kV1Curve)) {
    check_v1_curve_length(r, r.require(kV1Curve, Dtype::f32, 1).dims[0]);
    h.truncation_curve = r.column<float>(kV1Curve);
    check_v1_values(r, kV1Curve, h.truncation_curve);
  }
  return h;
}

}  // namespace

std::optional<HeldOutFigures> upgrade_held_out(const h5::Reader& r, int version) {
  if (version != 1) r.fail("/@format_version", fmt::format("no upgrade from format_version {}", version));
  return upgrade_v1_held_out(r);
}

}  // namespace phasecast::core
