// Every invariant of docs/package-format.md: the shape rules on dataset
// extents (package_shapes.h; the reader applies them before reading data),
// then the value rules on an in-memory package.
// Each failure is one line: "<source>: <dataset>: <expectation>, got <value>".

#include "package_fidelity.h"
#include "package_shapes.h"
#include "phasecast/core/kinematics_rows.h"
#include "phasecast/core/package.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>

namespace phasecast::core {
namespace {

class Checker {
 public:
  explicit Checker(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& message) const {
    throw PackageError(fmt::format("{}: {}: {}", source_, where, message));
  }

  template <class Derived>
  void finite(const std::string& where, const Eigen::DenseBase<Derived>& m) const {
    const auto* data = m.derived().data();
    for (Eigen::Index i = 0; i < m.size(); ++i) {
      if (!std::isfinite(data[i])) {
        fail(where, fmt::format("expected finite values, got {} at flat index {}", data[i], i));
      }
    }
  }

  template <class T>
  void index_range(const std::string& where, const T* data, size_t n, std::int64_t lo, std::int64_t hi,
                   const char* meaning) const {
    for (size_t i = 0; i < n; ++i) {
      const auto v = static_cast<std::int64_t>(data[i]);
      if (v < lo || v >= hi) {
        fail(where, fmt::format("expected {} in [{}, {}), got {} at flat index {}", meaning, lo, hi, v, i));
      }
    }
  }

 private:
  std::string source_;
};

void check_attributes(const Checker& c, const PackageAttributes& a) {
  if (a.format_version != kFormatVersion) {
    c.fail("/@format_version",
           fmt::format("unknown format_version {} (this build reads {})", a.format_version, kFormatVersion));
  }
  if (a.scene.empty()) c.fail("/@scene", "expected a non-empty scene name");
  if (!(std::isfinite(a.dt) && a.dt > 0))
    c.fail("/@dt", fmt::format("expected a positive time step in seconds, got {}", a.dt));
  if (!(std::isfinite(a.beta) && a.beta >= 0))
    c.fail("/@beta", fmt::format("expected a finite beta >= 0 (eq. 9), got {}", a.beta));
  if (!(std::isfinite(a.blend_lambda) && a.blend_lambda > 0)) {
    c.fail("/@blend_lambda", fmt::format("expected lambda > 0 in 1/s (eq. 12), got {}", a.blend_lambda));
  }
  for (const auto& [name, eps] : {std::pair{"/@eps_u", a.eps_u}, std::pair{"/@eps_a", a.eps_a}}) {
    if (!(eps >= 0 && eps < 1)) c.fail(name, fmt::format("expected a tolerance in [0, 1), got {}", eps));
  }
  if (a.camera) {
    for (float v : *a.camera) {
      if (!std::isfinite(v)) c.fail("/@camera", "expected finite camera values");
    }
  }
}

// ---- shapes: the extents of every dataset, agreeing with each other ---------------

std::string describe(const Extent& e) {
  std::string s;
  for (size_t i = 0; i < e.size(); ++i) s += (i ? "x" : "") + std::to_string(e[i]);
  return e.empty() ? "a scalar" : s;
}

class ShapeChecker {
 public:
  ShapeChecker(const Checker& c, const PackageShapes& shapes) : c_(c), shapes_(shapes) {}

  const Checker& checker() const { return c_; }
  bool has(const std::string& name) const { return shapes_.count(name) != 0; }

  // Extent i of `name` (0 if the dataset has fewer), for the sizes S, N, ...
  std::uint64_t dim(const std::string& name, size_t i) const {
    const Extent& e = of(name);
    return i < e.size() ? e[i] : 0;
  }

  void shape(const std::string& name, std::uint64_t rows, std::uint64_t cols, const char* meaning) const {
    if (of(name) != Extent{rows, cols}) {
      c_.fail(name,
              fmt::format("expected shape {} = {}x{}, got {}", meaning, rows, cols, describe(of(name))));
    }
  }

  void length(const std::string& name, std::uint64_t n, const char* meaning) const {
    if (of(name) != Extent{n}) {
      c_.fail(name, fmt::format("expected length {} = {}, got {}", meaning, n, describe(of(name))));
    }
  }

 private:
  const Extent& of(const std::string& name) const {
    const auto it = shapes_.find(name);
    if (it == shapes_.end()) c_.fail(name, "missing dataset");
    return it->second;
  }

  const Checker& c_;
  const PackageShapes& shapes_;
};

void check_mesh_shapes(const ShapeChecker& s) {
  const std::uint64_t S = s.dim("/mesh/rest_positions", 0);
  if (S == 0) s.checker().fail("/mesh/rest_positions", "expected at least one scene point");
  s.shape("/mesh/rest_positions", S, 3, "S x 3");
  const std::uint64_t F = s.dim("/mesh/triangles", 0);
  if (F == 0) s.checker().fail("/mesh/triangles", "expected at least one triangle");
  s.shape("/mesh/triangles", F, 3, "F x 3");
  s.shape("/mesh/normals", S, 3, "S x 3");
  s.length("/mesh/deformable", S, "S");
  s.length("/mesh/attached", S, "S");
}

void check_palette_shapes(const ShapeChecker& s) {
  const std::uint64_t D = s.dim("/palette/names", 0);
  if (D == 0) s.checker().fail("/palette/names", "expected at least one palette entry");
  const std::uint64_t k = s.dim("/palette/alpha_impulse", 1);
  s.shape("/palette/alpha_impulse", D, k, "D x k");
  s.shape("/palette/alpha_forcing", D, k, "D x k (k of alpha_impulse)");
  s.shape("/palette/transitions", D + 1, D, "(D+1) x D");
  s.length("/palette/on_end", D, "D");
  s.shape("/palette/kinematics", D, kKinematicsColumns, "D x 11 (axis_x, ..., pulse_tau)");
  s.length("/palette/group", D, "D");
  s.length("/palette/max_in_a_row", D, "D");
}

void check_reduction_shapes(const ShapeChecker& s) {
  const std::uint64_t M = 3 * s.dim("/mesh/rest_positions", 0);
  s.length("/reduction/mean_shape", M, "3S");
  const std::uint64_t r_u = s.dim("/reduction/U_u", 1);
  if (r_u == 0) s.checker().fail("/reduction/U_u", "expected rank r_u >= 1");
  s.shape("/reduction/U_u", M, r_u, "3S x r_u");
  const std::uint64_t n = s.dim("/reduction/singular_values", 0);
  if (n < r_u) {
    s.checker().fail("/reduction/singular_values",
                     fmt::format("expected at least r_u = {} values, got {}", r_u, n));
  }
  s.length("/reduction/rel_error", n, "that of singular_values");
}

void check_portrait_shapes(const ShapeChecker& s) {
  const std::uint64_t N = s.dim("/portrait/q_u", 0);
  if (N == 0) s.checker().fail("/portrait/q_u", "expected at least one state node");
  const std::uint64_t r_u = s.dim("/reduction/U_u", 1);
  const std::uint64_t r_a = s.has("/appearance/U_a") ? s.dim("/appearance/U_a", 1) : 0;
  s.shape("/portrait/q_u", N, r_u, "N x r_u");
  s.shape("/portrait/qdot_u", N, r_u, "N x r_u");
  s.shape("/portrait/q_a", N, r_a, "N x r_a");
  const std::uint64_t n_irf = s.dim("/portrait/irf_start", 0);
  if (n_irf == 0) s.checker().fail("/portrait/irf_start", "expected at least one IRF");
  s.length("/portrait/irf_length", n_irf, "n_irf");
  s.length("/portrait/irf_palette", n_irf, "n_irf");
  s.shape("/portrait/nearest_irf", N, s.dim("/palette/names", 0), "N x D");
  if (s.has("/portrait/support")) s.shape("/portrait/support", N, kSupportFloats, "N x 12");
}

// The held-out figures come together: present, they need their nodes and the
// four plain figures; each figure is one value, each spread two.
void check_held_out_shapes(const ShapeChecker& s, std::uint64_t r_a, std::uint64_t Na) {
  const auto any_figure = [&s] {
    for (const auto& f : kOptionalHeldOutFigures)
      if (s.has(f.name)) return true;
    for (const auto& f : kHeldOutSpreads)
      if (s.has(f.name)) return true;
    for (const auto& f : kHeldOutFigures)
      if (s.has(f.name)) return true;
    return s.has(kHeldOutCurve);
  };
  if (!s.has(kHeldOutNodes)) {
    if (any_figure())
      s.checker().fail(kHeldOutNodes, "expected the nodes of the held-out figures beside them");
    return;
  }
  for (const auto& f : kHeldOutFigures) s.length(f.name, 1, "1 (a figure)");
  for (const auto& f : kOptionalHeldOutFigures)
    if (s.has(f.name)) s.length(f.name, 1, "1 (a figure)");
  for (const auto& f : kHeldOutSpreads)
    if (s.has(f.name)) s.length(f.name, 2, "2 (10th and 90th percentile)");
  if (s.has(kHeldOutCurve)) {
    // One value per direction the clusters' SVD resolves: at least r_a, and
    // at most N_a - 1 (the centred fields sum to 0 under any weighting).
    const std::uint64_t K = s.dim(kHeldOutCurve, 0);
    if (K < std::max<std::uint64_t>(r_a, 1) || K + 1 > Na)
      s.checker().fail(kHeldOutCurve,
                       fmt::format("expected at least r_a = {} and at most N_a - 1 = {} values, got {}",
                                   std::max<std::uint64_t>(r_a, 1), Na - 1, K));
  }
}

void check_appearance_shapes(const ShapeChecker& s) {
  const std::uint64_t T = kTransferPerPoint * s.dim("/mesh/rest_positions", 0);
  s.length("/appearance/mean_transfer", T, "48S");
  const std::uint64_t r_a = s.dim("/appearance/U_a", 1);
  s.shape("/appearance/U_a", T, r_a, "48S x r_a");
  const std::uint64_t n = s.dim("/appearance/singular_values", 0);
  if (n < r_a) {
    s.checker().fail("/appearance/singular_values",
                     fmt::format("expected at least r_a = {} values, got {}", r_a, n));
  }
  s.length("/appearance/rel_error", n, "that of singular_values");
  const std::uint64_t Na = s.dim("/appearance/cluster_nodes", 0);
  if (Na == 0) s.checker().fail("/appearance/cluster_nodes", "expected at least one cluster node");
  s.shape("/appearance/nrbf_centers", Na, s.dim("/reduction/U_u", 1), "N_a x r_u");
  s.shape("/appearance/nrbf_weights", Na, r_a, "N_a x r_a");
  s.length("/appearance/nrbf_widths", Na, "N_a");
  s.length("/appearance/nrbf_regularization", 1, "1 (mu)");
  if (s.has("/appearance/interpolant")) s.length("/appearance/interpolant", 1, "1 (the interpolant's name)");
  if (s.has("/appearance/transfer_weighting"))
    s.length("/appearance/transfer_weighting", 1, "1 (the weighting's name)");
  // At most 2 (nrbf, knn), or affine-knn's (and affine-knn-slope's) k and its (1 + r_u) x r_a map.
  const std::uint64_t affine_knn = 1 + (1 + s.dim("/reduction/U_u", 1)) * r_a;
  if (s.has("/appearance/interpolant_parameters")) {
    const std::uint64_t m = s.dim("/appearance/interpolant_parameters", 0);
    if (m > 2 && m != affine_knn) {
      s.checker().fail(
          "/appearance/interpolant_parameters",
          fmt::format(
              "expected at most 2 values, or {} (affine-knn, affine-knn-slope: k and a (1 + r_u) x r_a "
              "map), got {}",
              affine_knn, m));
    }
  }
  if (s.has("/appearance/paper_rank")) s.length("/appearance/paper_rank", 1, "1 (the paper's r_a)");
  if (s.has("/appearance/transfer_sampling"))
    s.length("/appearance/transfer_sampling", 2, "2 (rays, bounces)");
  check_held_out_shapes(s, r_a, Na);
}

Extent extent(Eigen::Index rows, Eigen::Index cols) {
  return {static_cast<std::uint64_t>(rows), static_cast<std::uint64_t>(cols)};
}

template <class V>
Extent extent(const V& v) {
  return {static_cast<std::uint64_t>(v.size())};
}

void add_appearance_shapes(const Appearance& a, PackageShapes& s) {
  s["/appearance/mean_transfer"] = extent(a.mean_transfer);
  s["/appearance/U_a"] = extent(a.U_a.rows(), a.U_a.cols());
  s["/appearance/singular_values"] = extent(a.singular_values);
  s["/appearance/rel_error"] = extent(a.rel_error);
  s["/appearance/cluster_nodes"] = extent(a.cluster_nodes);
  s["/appearance/nrbf_centers"] = extent(a.nrbf_centers.rows(), a.nrbf_centers.cols());
  s["/appearance/nrbf_weights"] = extent(a.nrbf_weights.rows(), a.nrbf_weights.cols());
  s["/appearance/nrbf_widths"] = extent(a.nrbf_widths);
  s["/appearance/nrbf_regularization"] = {1};
  s["/appearance/interpolant"] = {1};
  s["/appearance/interpolant_parameters"] = extent(a.interpolant_parameters);
  s["/appearance/transfer_weighting"] = {1};
  if (a.held_out) add_held_out_shapes(*a.held_out, s);
  if (a.paper_rank > 0) s["/appearance/paper_rank"] = {1};
  if (a.transfer_rays > 0) s["/appearance/transfer_sampling"] = {2};
}

// ---- values: finiteness, indices, flags, the rules between values ----------------
// Each runs after check_shapes(), so every size it relies on has been checked.

void check_mesh(const Checker& c, const SceneMesh& m) {
  const Eigen::Index S = m.rest_positions.rows();
  c.finite("/mesh/rest_positions", m.rest_positions);
  c.index_range("/mesh/triangles", m.triangles.data(), static_cast<size_t>(m.triangles.size()), 0, S,
                "point indices");
  c.finite("/mesh/normals", m.normals);
  c.index_range("/mesh/deformable", m.deformable.data(), m.deformable.size(), 0, 2, "flags");
  c.index_range("/mesh/attached", m.attached.data(), m.attached.size(), 0, 2, "flags");
}

void check_kinematics(const Checker& c, const std::vector<SupportKinematics>& ks) {
  for (size_t i = 0; i < ks.size(); ++i) {
    const auto& k = ks[i];
    const std::string where = fmt::format("/palette/kinematics[{}]", i);
    const float values[] = {k.axis[0],  k.axis[1], k.axis[2],   k.pivot[0],  k.pivot[1],
                            k.pivot[2], k.rate,    k.range_min, k.range_max, k.pulse_tau};
    for (float v : values) {
      if (!std::isfinite(v)) c.fail(where, "expected finite values");
    }
    const float len = std::sqrt(k.axis[0] * k.axis[0] + k.axis[1] * k.axis[1] + k.axis[2] * k.axis[2]);
    if (std::abs(len - 1.0f) > 1e-3f) c.fail(where, fmt::format("expected a unit axis, got length {}", len));
    if (k.range_min > k.range_max) {
      c.fail(where, fmt::format("expected range_min <= range_max, got {} > {}", k.range_min, k.range_max));
    }
    if (k.pulse_tau < 0) c.fail(where, fmt::format("expected pulse_tau >= 0, got {}", k.pulse_tau));
  }
}

// A name read from the file as it may appear in a one-line message: control
// characters (a newline would split the line) written as \xNN.
std::string printable(const std::string& name) {
  std::string out;
  for (const char ch : name) {
    const auto u = static_cast<unsigned char>(ch);
    out += u < 0x20 || u == 0x7f ? fmt::format("\\x{:02x}", u) : std::string(1, ch);
  }
  return out;
}

void check_palette(const Checker& c, const ImpulsePalette& p) {
  const size_t D = p.names.size();
  std::set<std::string> seen;
  for (const auto& n : p.names) {
    if (n.empty()) c.fail("/palette/names", "expected non-empty entry names");
    if (!seen.insert(n).second)
      c.fail("/palette/names", fmt::format("expected unique names, got '{}' twice", printable(n)));
  }
  const auto Di = static_cast<Eigen::Index>(D);
  c.finite("/palette/alpha_impulse", p.alpha_impulse);
  c.finite("/palette/alpha_forcing", p.alpha_forcing);
  c.index_range("/palette/transitions", p.transitions.data(), static_cast<size_t>(p.transitions.size()), 0, 2,
                "flags");
  c.index_range("/palette/on_end", p.on_end.data(), D, kEndHold, Di,
                "-2 (hold), -1 (rest) or an entry index");
  check_kinematics(c, p.kinematics);
  c.index_range("/palette/group", p.group.data(), D, 0, Di, "an entry index");
  c.index_range("/palette/max_in_a_row", p.max_in_a_row.data(), D, 0, 1000000, "a count");
}

void check_reduction(const Checker& c, const Reduction& r, const SceneMesh& m) {
  const Eigen::Index M = 3 * m.rest_positions.rows();
  c.finite("/reduction/mean_shape", r.mean_shape);
  c.finite("/reduction/U_u", r.U_u);
  for (Eigen::Index i = 0; i < M; ++i) {
    if (m.deformable[static_cast<size_t>(i / 3)] == 0 && r.U_u.row(i).squaredNorm() != 0.0f) {
      c.fail("/reduction/U_u",
             fmt::format("expected zero rows for static points, got a non-zero row {} (point {})", i, i / 3));
    }
  }
  c.finite("/reduction/singular_values", r.singular_values);
  c.finite("/reduction/rel_error", r.rel_error);
}

void check_irfs(const Checker& c, const PhasePortrait& p, Eigen::Index N, int D) {
  const size_t n_irf = p.irf_start.size();
  c.index_range("/portrait/irf_start", p.irf_start.data(), n_irf, 0, N, "state nodes");
  c.index_range("/portrait/irf_palette", p.irf_palette.data(), n_irf, 0, D, "palette indices");
  for (size_t i = 0; i < n_irf; ++i) {
    if (p.irf_length[i] < 1 || p.irf_start[i] + static_cast<std::int64_t>(p.irf_length[i]) > N) {
      c.fail("/portrait/irf_length",
             fmt::format("expected IRF {} (start {}, length {}) to lie within the N = {} state nodes", i,
                         p.irf_start[i], p.irf_length[i], N));
    }
  }
  for (Eigen::Index j = 0; j < N; ++j) {
    for (int d = 0; d < D; ++d) {
      const std::int32_t irf = p.nearest_irf(j, d);
      if (irf == -1) continue;  // no IRF of entry d was sampled
      if (irf < 0 || static_cast<size_t>(irf) >= n_irf || p.irf_palette[static_cast<size_t>(irf)] != d) {
        c.fail("/portrait/nearest_irf",
               fmt::format("expected at [{}, {}] -1 or an IRF of palette entry {} among {}, got {}", j, d, d,
                           n_irf, irf));
      }
    }
  }
}

void check_portrait(const Checker& c, const PhasePortrait& p, int D) {
  c.finite("/portrait/q_u", p.q_u);
  c.finite("/portrait/qdot_u", p.qdot_u);
  c.finite("/portrait/q_a", p.q_a);
  check_irfs(c, p, p.q_u.rows(), D);
  c.finite("/portrait/support", p.support);
}

// Fig. 12 out of sample: relative l2 norms in [0, 1] that never rise with the
// rank (a larger basis spans the smaller), and that agree at r_a with the
// l2 truncation measured with the stored U_a (float round-off aside).
void check_held_out_truncation_curve(const Checker& c, const HeldOutFigures& h, int r_a) {
  const VectorXf& curve = h.truncation_curve;
  constexpr float kRoundOff = 1e-3f;
  for (Eigen::Index i = 0; i < curve.size(); ++i) {
    if (!(curve[i] >= 0 && curve[i] <= 1 + kRoundOff))
      c.fail(kHeldOutCurve,
             fmt::format("expected relative errors in [0, 1], got {} at rank {}", curve[i], i + 1));
    if (i > 0 && curve[i] > curve[i - 1] + kRoundOff)
      c.fail(kHeldOutCurve, fmt::format("expected no rise with the rank, got {} at rank {} after {}",
                                        curve[i], i + 1, curve[i - 1]));
  }
  if (curve.size() > 0 && r_a > 0 && h.l2_truncation &&
      std::abs(curve[r_a - 1] - *h.l2_truncation) > kRoundOff)
    c.fail(kHeldOutCurve, fmt::format("expected {} at r_a = {} (the held-out l2_truncation), got {}",
                                      *h.l2_truncation, r_a, curve[r_a - 1]));
}

void check_held_out(const Checker& c, const HeldOutFigures& h, int r_a, Eigen::Index N) {
  c.index_range(kHeldOutNodes, h.nodes.data(), h.nodes.size(), 0, N, "state nodes");
  const auto error = [&c](const char* name, float v) {
    if (!(v >= 0 && std::isfinite(v))) c.fail(name, fmt::format("expected a finite error >= 0, got {}", v));
  };
  for (const auto& f : kHeldOutFigures) error(f.name, h.*f.member);
  for (const auto& f : kOptionalHeldOutFigures)
    if (const auto& v = h.*f.member) error(f.name, *v);
  for (const auto& f : kHeldOutSpreads) {
    if (const auto& v = h.*f.member) {
      error(f.name, v->p10);
      error(f.name, v->p90);
      if (v->p10 > v->p90) c.fail(f.name, "expected the 10th percentile <= the 90th");
    }
  }
  check_held_out_truncation_curve(c, h, r_a);
}

void check_appearance(const Checker& c, const Appearance& a, Eigen::Index N) {
  c.finite("/appearance/mean_transfer", a.mean_transfer);
  c.finite("/appearance/U_a", a.U_a);
  c.finite("/appearance/singular_values", a.singular_values);
  c.finite("/appearance/rel_error", a.rel_error);
  c.index_range("/appearance/cluster_nodes", a.cluster_nodes.data(), a.cluster_nodes.size(), 0, N,
                "state nodes");
  c.finite("/appearance/nrbf_centers", a.nrbf_centers);
  c.finite("/appearance/nrbf_weights", a.nrbf_weights);
  for (Eigen::Index i = 0; i < a.nrbf_widths.size(); ++i) {
    if (!(a.nrbf_widths[i] > 0 && std::isfinite(a.nrbf_widths[i]))) {
      c.fail("/appearance/nrbf_widths",
             fmt::format("expected positive finite widths, got {} at {}", a.nrbf_widths[i], i));
    }
  }
  if (!(a.nrbf_regularization >= 0 && std::isfinite(a.nrbf_regularization))) {
    c.fail("/appearance/nrbf_regularization",
           fmt::format("expected a finite value >= 0, got {}", a.nrbf_regularization));
  }
  const bool affine = is_affine_interpolant(a.interpolant);
  if (a.interpolant != "nrbf" && a.interpolant != "knn" && !affine) {
    c.fail("/appearance/interpolant",
           fmt::format("expected \"nrbf\", \"knn\", \"affine-knn\" or \"affine-knn-slope\", got \"{}\"",
                       a.interpolant));
  }
  const Eigen::Index affine_knn = 1 + (1 + a.nrbf_centers.cols()) * a.U_a.cols();
  const Eigen::Index m = a.interpolant_parameters.size();
  if (affine ? m != affine_knn : m > 2) {
    c.fail("/appearance/interpolant_parameters",
           fmt::format("expected {} for interpolant \"{}\", got {} values",
                       affine ? fmt::format("{} (k and a (1 + r_u) x r_a map)", affine_knn)
                              : std::string("at most 2"),
                       a.interpolant, m));
  }
  // knn's k counts neighbours among the N_a centres.
  if ((affine || a.interpolant == "knn") && m >= 1) {
    const float k = a.interpolant_parameters[0];
    if (!(k >= 1 && k <= static_cast<float>(a.nrbf_centers.rows()) && k == std::floor(k))) {
      c.fail("/appearance/interpolant_parameters",
             fmt::format("expected k (the first value) a whole number in 1..{} (N_a), got {}",
                         a.nrbf_centers.rows(), k));
    }
  }
  c.finite("/appearance/interpolant_parameters", a.interpolant_parameters);
  if (a.transfer_weighting != "equal" && a.transfer_weighting != "cluster size")
    c.fail("/appearance/transfer_weighting",
           fmt::format("expected \"equal\" or \"cluster size\", got \"{}\"", a.transfer_weighting));
  if (a.held_out) check_held_out(c, *a.held_out, a.rank(), N);
  if (a.paper_rank < 0)
    c.fail("/appearance/paper_rank", fmt::format("expected r_a >= 0, got {}", a.paper_rank));
  if (a.transfer_rays < 0 || a.transfer_bounces < 0 || (a.transfer_rays == 0 && a.transfer_bounces > 0))
    c.fail("/appearance/transfer_sampling", fmt::format("expected rays >= 1 and bounces >= 0, got {} and {}",
                                                        a.transfer_rays, a.transfer_bounces));
}

}  // namespace

int ImpulsePalette::index_of(const std::string& name) const {
  const auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? -1 : static_cast<int>(it - names.begin());
}

bool ImpulsePalette::allowed(int from, int to) const {
  if (to < 0 || to >= size() || from < -1 || from >= size()) return false;
  return transitions(from + 1, to) != 0;
}

bool within_run_limit(const std::vector<std::int32_t>& group, const std::vector<std::int32_t>& max_in_a_row,
                      const PaletteRun& run, int to) {
  const auto d = static_cast<size_t>(to);
  const int limit = max_in_a_row[d];
  return limit == 0 || run.length == 0 || run.group != group[d] ||
         run.length < static_cast<std::uint32_t>(limit);
}

PaletteRun extended_run(const std::vector<std::int32_t>& group, const PaletteRun& run, int to) {
  const std::int32_t g = group[static_cast<size_t>(to)];
  return {g, run.length > 0 && run.group == g ? run.length + 1 : 1};
}

int frames_of_support_motion(double rate, double range_min, double range_max, double s, double dt,
                             int max_frames) {
  if (!(range_max > range_min) || std::abs(rate) < 1e-12) return max_frames;
  const double room = rate > 0 ? range_max - s : s - range_min;
  // A whole frame of motion must fit: a door at its stop cannot open further.
  const double frames = std::floor(room / (std::abs(rate) * dt) + 1e-6);
  return static_cast<int>(std::clamp(frames, 0.0, static_cast<double>(max_frames)));
}

bool ImpulsePalette::within_run_limit(const PaletteRun& run, int to) const {
  return core::within_run_limit(group, max_in_a_row, run, to);
}

PaletteRun ImpulsePalette::extended(const PaletteRun& run, int to) const {
  return extended_run(group, run, to);
}

bool ImpulsePalette::can_move_support(int to, double s, double dt) const {
  const auto& k = kinematics[static_cast<size_t>(to)];
  if (k.pulse_tau > 0) return true;  // a jolt returns to rest wherever the support stands
  return frames_of_support_motion(k.rate, k.range_min, k.range_max, s, dt, 1) >= 1;
}

void add_held_out_shapes(const HeldOutFigures& h, PackageShapes& s) {
  s[kHeldOutNodes] = extent(h.nodes);
  for (const auto& f : kHeldOutFigures) s[f.name] = {1};
  for (const auto& f : kOptionalHeldOutFigures)
    if (h.*f.member) s[f.name] = {1};
  for (const auto& f : kHeldOutSpreads)
    if (h.*f.member) s[f.name] = {2};
  if (h.truncation_curve.size() > 0) s[kHeldOutCurve] = extent(h.truncation_curve);
}

PackageShapes shapes_of(const ScenePackage& p) {
  const auto& m = p.mesh;
  const auto& pal = p.palette;
  const auto& r = p.reduction;
  const auto& pp = p.portrait;
  PackageShapes s = {
      {"/mesh/rest_positions", extent(m.rest_positions.rows(), m.rest_positions.cols())},
      {"/mesh/triangles", extent(m.triangles.rows(), m.triangles.cols())},
      {"/mesh/normals", extent(m.normals.rows(), m.normals.cols())},
      {"/mesh/deformable", extent(m.deformable)},
      {"/mesh/attached", extent(m.attached)},
      {"/palette/names", extent(pal.names)},
      {"/palette/alpha_impulse", extent(pal.alpha_impulse.rows(), pal.alpha_impulse.cols())},
      {"/palette/alpha_forcing", extent(pal.alpha_forcing.rows(), pal.alpha_forcing.cols())},
      {"/palette/transitions", extent(pal.transitions.rows(), pal.transitions.cols())},
      {"/palette/on_end", extent(pal.on_end)},
      {"/palette/kinematics", {pal.kinematics.size(), static_cast<std::uint64_t>(kKinematicsColumns)}},
      {"/palette/group", extent(pal.group)},
      {"/palette/max_in_a_row", extent(pal.max_in_a_row)},
      {"/reduction/mean_shape", extent(r.mean_shape)},
      {"/reduction/U_u", extent(r.U_u.rows(), r.U_u.cols())},
      {"/reduction/singular_values", extent(r.singular_values)},
      {"/reduction/rel_error", extent(r.rel_error)},
      {"/portrait/q_u", extent(pp.q_u.rows(), pp.q_u.cols())},
      {"/portrait/qdot_u", extent(pp.qdot_u.rows(), pp.qdot_u.cols())},
      {"/portrait/q_a", extent(pp.q_a.rows(), pp.q_a.cols())},
      {"/portrait/irf_start", extent(pp.irf_start)},
      {"/portrait/irf_length", extent(pp.irf_length)},
      {"/portrait/irf_palette", extent(pp.irf_palette)},
      {"/portrait/nearest_irf", extent(pp.nearest_irf.rows(), pp.nearest_irf.cols())},
  };
  // A support of no rows is an absent one: write_package() leaves it out.
  if (pp.support.rows() != 0) s["/portrait/support"] = extent(pp.support.rows(), pp.support.cols());
  if (p.appearance) add_appearance_shapes(*p.appearance, s);
  if (p.fidelity) add_fidelity_shapes(*p.fidelity, s);
  return s;
}

namespace {

// /fidelity/: every figure one value; the adaptive four together or not at all.
void check_fidelity_shapes(const ShapeChecker& s) {
  std::vector<const char*> adaptive{kFidelityTarget, kFidelityTargetMet};
  adaptive.insert(adaptive.end(), std::begin(kFidelityAdaptiveCounts), std::end(kFidelityAdaptiveCounts));
  std::vector<const char*> required{kFidelitySeed};
  required.insert(required.end(), std::begin(kFidelityCounts), std::end(kFidelityCounts));
  required.insert(required.end(), std::begin(kFidelityNrmse), std::end(kFidelityNrmse));
  const auto present = [&s](const std::vector<const char*>& names) {
    return std::count_if(names.begin(), names.end(), [&s](const char* n) { return s.has(n); });
  };
  if (present(required) == 0 && present(adaptive) == 0) return;
  for (const char* name : required) s.length(name, 1, "1 (a figure)");
  if (present(adaptive) == 0) return;
  for (const char* name : adaptive) s.length(name, 1, "1 (a figure of adaptive sampling)");
}

}  // namespace

void check_shapes(const PackageShapes& shapes, const std::string& source) {
  const Checker c(source);
  const ShapeChecker s(c, shapes);
  check_mesh_shapes(s);
  check_palette_shapes(s);
  check_reduction_shapes(s);
  check_portrait_shapes(s);
  if (s.has("/appearance/U_a")) check_appearance_shapes(s);
  check_fidelity_shapes(s);
}

namespace {

// Counts >= 0 with each "within" at most its whole; NRMSE figures finite, >= 0, median <= 90th.
void check_fidelity(const Checker& c, const PlaybackFidelity& p) {
  for (const auto& [name, v] :
       {std::pair{"/fidelity/schedules", p.schedules}, std::pair{"/fidelity/items", p.items},
        std::pair{"/fidelity/sampled_irfs", p.sampled_irfs}, std::pair{"/fidelity/rounds", p.rounds}})
    if (v < 0) c.fail(name, fmt::format("expected a count >= 0, got {}", v));
  if (!(p.moving_within >= 0 && p.moving_within <= p.moving))
    c.fail("/fidelity/moving_within",
           fmt::format("expected 0..{} (the moving segments), got {}", p.moving, p.moving_within));
  if (!(p.switches_within >= 0 && p.switches_within <= p.switches))
    c.fail("/fidelity/switches_within",
           fmt::format("expected 0..{} (the switches), got {}", p.switches, p.switches_within));
  if (!(p.median_nrmse >= 0 && std::isfinite(p.median_nrmse)))
    c.fail("/fidelity/median_nrmse", fmt::format("expected a finite NRMSE >= 0, got {}", p.median_nrmse));
  if (!(p.p90_nrmse >= p.median_nrmse && std::isfinite(p.p90_nrmse)))
    c.fail("/fidelity/p90_nrmse", fmt::format("expected a finite NRMSE >= the median, got {}", p.p90_nrmse));
  if (!(p.seed >= 0 && p.seed == std::floor(p.seed) && p.seed < 9007199254740992.0))
    c.fail("/fidelity/seed", fmt::format("expected a whole number in [0, 2^53), got {}", p.seed));
  if (p.target_median_nrmse && !(*p.target_median_nrmse > 0 && std::isfinite(*p.target_median_nrmse)))
    c.fail("/fidelity/target_median_nrmse",
           fmt::format("expected a finite NRMSE > 0, got {}", *p.target_median_nrmse));
}

}  // namespace

void validate_package(const ScenePackage& pkg, const std::string& source) {
  const Checker c(source);
  check_attributes(c, pkg.attributes);
  check_shapes(shapes_of(pkg), source);
  check_mesh(c, pkg.mesh);
  check_palette(c, pkg.palette);
  check_reduction(c, pkg.reduction, pkg.mesh);
  check_portrait(c, pkg.portrait, pkg.palette.size());
  if (pkg.appearance) check_appearance(c, *pkg.appearance, pkg.portrait.nodes());
  if (pkg.fidelity) check_fidelity(c, *pkg.fidelity);
}

}  // namespace phasecast::core
