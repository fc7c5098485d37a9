// Every invariant of docs/package-format.md, checked on an in-memory package.
// Each failure is one line: "<source>: <dataset>: <expectation>, got <value>".

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

  template <class M>
  void shape(const std::string& where, const M& m, Eigen::Index rows, Eigen::Index cols,
             const char* meaning) const {
    if (m.rows() != rows || m.cols() != cols) {
      fail(where,
           fmt::format("expected shape {} = {}x{}, got {}x{}", meaning, rows, cols, m.rows(), m.cols()));
    }
  }

  template <class V>
  void length(const std::string& where, const V& v, size_t n, const char* meaning) const {
    if (static_cast<size_t>(v.size()) != n) {
      fail(where, fmt::format("expected length {} = {}, got {}", meaning, n, v.size()));
    }
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

void check_mesh(const Checker& c, const SceneMesh& m) {
  const Eigen::Index S = m.rest_positions.rows();
  if (S == 0) c.fail("/mesh/rest_positions", "expected at least one scene point");
  c.shape("/mesh/rest_positions", m.rest_positions, S, 3, "S x 3");
  c.finite("/mesh/rest_positions", m.rest_positions);
  if (m.triangles.rows() == 0) c.fail("/mesh/triangles", "expected at least one triangle");
  c.shape("/mesh/triangles", m.triangles, m.triangles.rows(), 3, "F x 3");
  c.index_range("/mesh/triangles", m.triangles.data(), static_cast<size_t>(m.triangles.size()), 0, S,
                "point indices");
  c.shape("/mesh/normals", m.normals, S, 3, "S x 3");
  c.finite("/mesh/normals", m.normals);
  c.length("/mesh/deformable", m.deformable, static_cast<size_t>(S), "S");
  c.index_range("/mesh/deformable", m.deformable.data(), m.deformable.size(), 0, 2, "flags");
  c.length("/mesh/attached", m.attached, static_cast<size_t>(S), "S");
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

void check_palette(const Checker& c, const ImpulsePalette& p) {
  const size_t D = p.names.size();
  if (D == 0) c.fail("/palette/names", "expected at least one palette entry");
  std::set<std::string> seen;
  for (const auto& n : p.names) {
    if (n.empty()) c.fail("/palette/names", "expected non-empty entry names");
    if (!seen.insert(n).second)
      c.fail("/palette/names", fmt::format("expected unique names, got '{}' twice", n));
  }
  const auto Di = static_cast<Eigen::Index>(D);
  c.shape("/palette/alpha_impulse", p.alpha_impulse, Di, p.alpha_impulse.cols(), "D x k");
  c.shape("/palette/alpha_forcing", p.alpha_forcing, Di, p.alpha_impulse.cols(),
          "D x k (k of alpha_impulse)");
  c.finite("/palette/alpha_impulse", p.alpha_impulse);
  c.finite("/palette/alpha_forcing", p.alpha_forcing);
  c.shape("/palette/transitions", p.transitions, Di + 1, Di, "(D+1) x D");
  c.index_range("/palette/transitions", p.transitions.data(), static_cast<size_t>(p.transitions.size()), 0, 2,
                "flags");
  c.length("/palette/on_end", p.on_end, D, "D");
  c.index_range("/palette/on_end", p.on_end.data(), D, kEndHold, Di,
                "-2 (hold), -1 (rest) or an entry index");
  c.length("/palette/kinematics", p.kinematics, D, "D rows");
  check_kinematics(c, p.kinematics);
  c.length("/palette/group", p.group, D, "D");
  c.index_range("/palette/group", p.group.data(), D, 0, Di, "an entry index");
  c.length("/palette/max_in_a_row", p.max_in_a_row, D, "D");
  c.index_range("/palette/max_in_a_row", p.max_in_a_row.data(), D, 0, 1000000, "a count");
}

void check_reduction(const Checker& c, const Reduction& r, const SceneMesh& m) {
  const Eigen::Index M = 3 * m.rest_positions.rows();
  c.length("/reduction/mean_shape", r.mean_shape, static_cast<size_t>(M), "3S");
  c.finite("/reduction/mean_shape", r.mean_shape);
  if (r.U_u.cols() == 0) c.fail("/reduction/U_u", "expected rank r_u >= 1");
  c.shape("/reduction/U_u", r.U_u, M, r.U_u.cols(), "3S x r_u");
  c.finite("/reduction/U_u", r.U_u);
  for (Eigen::Index i = 0; i < M; ++i) {
    if (m.deformable[static_cast<size_t>(i / 3)] == 0 && r.U_u.row(i).squaredNorm() != 0.0f) {
      c.fail("/reduction/U_u",
             fmt::format("expected zero rows for static points, got a non-zero row {} (point {})", i, i / 3));
    }
  }
  const auto n = static_cast<size_t>(r.singular_values.size());
  if (n < static_cast<size_t>(r.U_u.cols())) {
    c.fail("/reduction/singular_values",
           fmt::format("expected at least r_u = {} values, got {}", r.U_u.cols(), n));
  }
  c.finite("/reduction/singular_values", r.singular_values);
  c.length("/reduction/rel_error", r.rel_error, n, "that of singular_values");
  c.finite("/reduction/rel_error", r.rel_error);
}

void check_irfs(const Checker& c, const PhasePortrait& p, Eigen::Index N, int D) {
  const size_t n_irf = p.irf_start.size();
  if (n_irf == 0) c.fail("/portrait/irf_start", "expected at least one IRF");
  c.length("/portrait/irf_length", p.irf_length, n_irf, "n_irf");
  c.length("/portrait/irf_palette", p.irf_palette, n_irf, "n_irf");
  c.index_range("/portrait/irf_start", p.irf_start.data(), n_irf, 0, N, "state nodes");
  c.index_range("/portrait/irf_palette", p.irf_palette.data(), n_irf, 0, D, "palette indices");
  for (size_t i = 0; i < n_irf; ++i) {
    if (p.irf_length[i] < 1 || p.irf_start[i] + static_cast<std::int64_t>(p.irf_length[i]) > N) {
      c.fail("/portrait/irf_length",
             fmt::format("expected IRF {} (start {}, length {}) to lie within the N = {} state nodes", i,
                         p.irf_start[i], p.irf_length[i], N));
    }
  }
  c.shape("/portrait/nearest_irf", p.nearest_irf, N, D, "N x D");
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

void check_portrait(const Checker& c, const PhasePortrait& p, int r_u, int r_a, int D) {
  const Eigen::Index N = p.q_u.rows();
  if (N == 0) c.fail("/portrait/q_u", "expected at least one state node");
  c.shape("/portrait/q_u", p.q_u, N, r_u, "N x r_u");
  c.finite("/portrait/q_u", p.q_u);
  c.shape("/portrait/qdot_u", p.qdot_u, N, r_u, "N x r_u");
  c.finite("/portrait/qdot_u", p.qdot_u);
  c.shape("/portrait/q_a", p.q_a, N, r_a, "N x r_a");
  c.finite("/portrait/q_a", p.q_a);
  check_irfs(c, p, N, D);
  if (p.support.rows() != 0) {
    c.shape("/portrait/support", p.support, N, kSupportFloats, "N x 12");
    c.finite("/portrait/support", p.support);
  }
}

void check_appearance(const Checker& c, const Appearance& a, Eigen::Index S, Eigen::Index N, int r_u) {
  const Eigen::Index T = kTransferPerPoint * S;
  c.length("/appearance/mean_transfer", a.mean_transfer, static_cast<size_t>(T), "48S");
  c.finite("/appearance/mean_transfer", a.mean_transfer);
  c.shape("/appearance/U_a", a.U_a, T, a.U_a.cols(), "48S x r_a");
  c.finite("/appearance/U_a", a.U_a);
  const auto n = static_cast<size_t>(a.singular_values.size());
  if (n < static_cast<size_t>(a.U_a.cols())) {
    c.fail("/appearance/singular_values",
           fmt::format("expected at least r_a = {} values, got {}", a.U_a.cols(), n));
  }
  c.finite("/appearance/singular_values", a.singular_values);
  c.length("/appearance/rel_error", a.rel_error, n, "that of singular_values");
  c.finite("/appearance/rel_error", a.rel_error);
  const size_t Na = a.cluster_nodes.size();
  if (Na == 0) c.fail("/appearance/cluster_nodes", "expected at least one cluster node");
  c.index_range("/appearance/cluster_nodes", a.cluster_nodes.data(), Na, 0, N, "state nodes");
  const auto Nai = static_cast<Eigen::Index>(Na);
  c.shape("/appearance/nrbf_centers", a.nrbf_centers, Nai, r_u, "N_a x r_u");
  c.finite("/appearance/nrbf_centers", a.nrbf_centers);
  c.shape("/appearance/nrbf_weights", a.nrbf_weights, Nai, a.U_a.cols(), "N_a x r_a");
  c.finite("/appearance/nrbf_weights", a.nrbf_weights);
  c.length("/appearance/nrbf_widths", a.nrbf_widths, Na, "N_a");
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

void validate_package(const ScenePackage& pkg, const std::string& source) {
  const Checker c(source);
  check_attributes(c, pkg.attributes);
  check_mesh(c, pkg.mesh);
  check_palette(c, pkg.palette);
  check_reduction(c, pkg.reduction, pkg.mesh);
  check_portrait(c, pkg.portrait, pkg.rank_u(), pkg.rank_a(), pkg.palette.size());
  if (pkg.appearance) {
    check_appearance(c, *pkg.appearance, pkg.mesh.rest_positions.rows(), pkg.portrait.nodes(), pkg.rank_u());
  }
}

}  // namespace phasecast::core
