// The reports of the sample and reduce stages in words (report_text.h).

#include "phasecast/precompute/pipeline/report_text.h"

#include "phasecast/core/package_summary.h"
#include "phasecast/precompute/pipeline/contact_report.h"

#include <fmt/format.h>

#include <cmath>
#include <string>
#include <vector>

namespace phasecast::precompute {
namespace {

// "deformable points 74 % / 88 % (0.0873), props 26 % / 12 % (0.0552); SH band 0 ...": each
// part's share of the variation and of the residual, and its relative error.
std::string residual_parts(const ResidualByPart& r) {
  const auto part = [](const char* name, const PartOfResidual& x) {
    return fmt::format("{} {:.0f} % / {:.0f} % ({:.4f})", name, 100 * x.of_data, 100 * x.of_residual,
                       x.relative);
  };
  return fmt::format("{}, {}; SH band {}, {}, {}, {}", part("deformable points", r.points[0]),
                     part("props", r.points[1]), part("0", r.bands[0]), part("1", r.bands[1]),
                     part("2", r.bands[2]), part("3", r.bands[3]));
}

void append_residual_parts(std::string& out, const AppearanceStageReport& report) {
  out += fmt::format(
      "appearance: where the truncation error lives (share of the variation about M-bar / of what U_a "
      "leaves of it (relative error)): clusters {:.4f}: {}\n",
      report.clusters_residual.relative, residual_parts(report.clusters_residual));
  if (const auto& h = report.held_out_residual)
    out += fmt::format("  held-out nodes {:.4f}: {}\n", h->relative, residual_parts(*h));
}

// The served basis against one of the picking half's own fields, with the
// paired verdict (a single draw's figures alone would call any difference).
void append_basis_comparison(std::string& out, const BasisComparison& b, Eigen::Index clusters,
                             Eigen::Index r) {
  const auto& g = b.drawn_gain;
  const std::string verdict =
      g.beyond_noise()    ? "the drawn basis is the better one: other states would give a better basis"
      : -g.gain > g.noise ? "the clusters' basis is the better one: as many random states miss more"
                          : "within noise of each other";
  out += fmt::format(
      "appearance: truncation alone at the reported half, relative to the nodes' own variation (Frobenius / "
      "l2): the {} clusters' basis {:.4f} / {:.4f}; a rank-{} basis of the picking half's own {} fields "
      "(random states) {:.4f} / {:.4f}, which leaves {:.1f} % {} squared error, noise {} (95 % t "
      "interval of the paired differences): {}{}\n",
      clusters, b.served.of_variation, b.served.l2_of_variation, r, b.drawn_fields, b.drawn.of_variation,
      b.drawn.l2_of_variation, 100 * std::abs(g.gain), g.gain >= 0 ? "less" : "more",
      std::isfinite(g.noise) ? fmt::format("{:.1f} %", 100 * g.noise) : "unbounded", verdict,
      b.drawn_fields < clusters
          ? fmt::format(" (from fewer fields than the {} clusters: --held-out {} compares "
                        "like with like)",
                        clusters, 2 * clusters)
          : std::string());
}

// How --held-out-target set r_a, at the picking half (the reported half never saw it).
void append_rank_choice(std::string& out, const HeldOutRankChoice& c) {
  if (c.reached) {
    out += fmt::format(
        "appearance: r_a = {}, the least rank whose truncation alone at the picking half's {} nodes "
        "(relative l2, equal weights) is at most {:.4f}: it reads {:.4f}\n",
        c.rank, c.picking_nodes, c.target, c.truncation);
  } else {
    out += fmt::format(
        "appearance: no rank of the clusters brings the truncation at the picking half's {} nodes to {:.4f} "
        "(all {} directions leave {:.4f}): r_a = {}, all of them (more clusters lower what they leave)\n",
        c.picking_nodes, c.target, c.rank, c.truncation, c.rank);
  }
}

void append_held_out(std::string& out, const core::HeldOutFigures& h, Eigen::Index r, int paper_rank) {
  if (h.l2_total && h.l2_truncation && h.clusters_l2_truncation && h.l2_floor) {
    out += fmt::format(
        "appearance: held-out error over {} nodes {:.4f} = truncation {:.4f} + interpolation {:.4f} (in "
        "quadrature, relative to |M - M-bar|); {:.4f} of |M|; relative l2 norm (the paper's relErr) {:.4f}, "
        "truncation alone {:.4f}, the clusters' own truncation over as many of them (all, if fewer) {:.4f}, "
        "the least any rank-{} model about M-bar reaches at those nodes {:.4f}\n",
        h.nodes.size(), h.total, h.truncation, h.interpolation, h.of_transfer, *h.l2_total, *h.l2_truncation,
        *h.clusters_l2_truncation, r, *h.l2_floor);
  }
  if (h.of_variation && h.l2_of_variation && h.l2_floor_of_variation) {
    out += fmt::format(
        "appearance: relative to the nodes' own variation |M - their mean| (no model moves it): {:.4f}, "
        "relative l2 {:.4f}; the least any rank-{} model reaches there, whatever its mean, {:.4f}\n",
        *h.of_variation, *h.l2_of_variation, r, *h.l2_floor_of_variation);
  }
  if (h.l2_total_spread && h.l2_truncation_spread) {
    out += fmt::format(
        "appearance: over resampled held-out nodes (10th-90th percentile) relative l2 {:.4f}-{:.4f}, "
        "truncation alone {:.4f}-{:.4f}{}\n",
        h.l2_total_spread->p10, h.l2_total_spread->p90, h.l2_truncation_spread->p10,
        h.l2_truncation_spread->p90,
        h.l2_of_variation_spread ? fmt::format("; relative l2 of their own variation {:.4f}-{:.4f}",
                                               h.l2_of_variation_spread->p10, h.l2_of_variation_spread->p90)
                                 : std::string());
  }
  if (const auto& curve = h.truncation_curve; curve.size() > 0) {
    out += fmt::format("appearance: held-out truncation by rank (Fig. 12 out of sample, relative l2): {}\n",
                       core::held_out_curve_text(
                           std::vector<double>(curve.begin(), curve.end()), static_cast<int>(r), paper_rank,
                           h.clusters_l2_truncation ? *h.clusters_l2_truncation : std::nan("")));
  }
}

void append_appearance_report(std::string& out, const core::Appearance& a,
                              const AppearanceStageReport& report) {
  const int r = a.rank();
  const bool has_next = r > 0 && r < a.singular_values.size() && a.singular_values[0] > 0;
  out += fmt::format(
      "appearance: N_a = {} clusters, {} scene points, r_a = {} (of the paper's A_a: truncation error {:.4f} "
      "on the clusters, sigma_{{r+1}}/sigma_1 {}, the paper's relErr); U_a and M-bar from the fields "
      "weighted "
      "{}\n",
      a.clusters(), a.mean_transfer.size() / core::kTransferPerPoint, r, r > 0 ? a.rel_error[r - 1] : 0.0f,
      has_next ? fmt::format("{:.4f}", a.singular_values[r] / a.singular_values[0]) : std::string("n/a"),
      a.transfer_weighting);
  if (const auto& c = report.rank_choice) append_rank_choice(out, *c);
  for (const auto& c : report.candidates) {
    const auto& f = c.interpolant;
    const std::string params =
        f.kind == InterpolantKind::nrbf
            ? fmt::format("width scale {}, lambda {:g}", f.width_scale, f.nrbf.regularization)
        : has_affine_map(f.kind) ? fmt::format("k = {}, ridge {:g}", f.neighbours, f.nrbf.regularization)
                                 : fmt::format("k = {}", f.neighbours);
    out += fmt::format("  {} weights, interpolant {} ({}): leave-one-out {:.4f}", weighting_name(c.weighting),
                       interpolant_name(f.kind), params, f.leave_one_out);
    if (a.held_out)
      out += fmt::format(
          ", held-out error of |M| {:.4f} (picking half) / {:.4f} (reported half), of the nodes' own "
          "variation {:.4f} / {:.4f}",
          c.selection.of_transfer, c.test.of_transfer, c.selection.of_variation, c.test.of_variation);
    out += fmt::format("{}\n", &c == &report.candidates.front() ? "  <- kept" : "");
  }
  if (const auto& g = report.weighting_gain) {
    out += fmt::format(
        "appearance: cluster sizes leave {:.1f} % {} squared error than equal weights at the picking "
        "half's nodes, noise {} (95 % t interval of the paired differences): {}\n",
        100 * std::abs(g->gain), g->gain >= 0 ? "less" : "more",
        std::isfinite(g->noise) ? fmt::format("{:.1f} %", 100 * g->noise) : "unbounded",
        g->beyond_noise() ? "beyond it, cluster sizes kept"
        : g->gain > 0     ? "within it, the paper's equal weights kept"
                          : "the paper's equal weights kept");
  }
  if (a.held_out) append_held_out(out, *a.held_out, r, a.paper_rank);
  if (const auto& b = report.basis_comparison) append_basis_comparison(out, *b, a.clusters(), r);
  if (r > 0) append_residual_parts(out, report);
}

}  // namespace

std::string sample_report_text(const SampleReport& r) {
  std::string out = fmt::format("wrote {} ({} IRFs, {} state nodes; chain stores merged in {:.1f} s)\n",
                                r.orbits.string(), r.irfs, r.frames, r.merge_seconds);
  if (r.contact) out += contact_line(*r.contact, r.close_distance) + "\n";
  return out;
}

std::string appearance_report_text(const core::Appearance& appearance, const AppearanceStageReport& report) {
  std::string out;
  append_appearance_report(out, appearance, report);
  return out;
}

std::string reduce_report_text(const ReduceReport& r) {
  const core::ScenePackage& p = r.package;
  std::string out;
  if (r.appearance && p.appearance) append_appearance_report(out, *p.appearance, r.appearance->stage);
  out += fmt::format(
      "wrote {}: N = {} state nodes, {} IRFs ({} short and {} dead ends dropped), r_u = {} (error {:.4f}), "
      "r_a = {}, beta = {:.4g}\n",
      r.package_path.string(), p.portrait.nodes(), p.portrait.irf_count(), r.dropped_short,
      r.dropped_dead_end, p.rank_u(), core::displacement_error_at_rank(p, p.rank_u()), p.rank_a(),
      p.attributes.beta);
  std::string entries;
  for (const auto& e : r.entries) {
    entries +=
        fmt::format("{}'{}' {} sampled, {} kept", entries.empty() ? "" : "; ", e.entry, e.sampled, e.kept);
    if (e.dropped_short + e.dropped_dead_end > 0)
      entries += fmt::format(" ({} short, {} dead ends dropped)", e.dropped_short, e.dropped_dead_end);
  }
  if (!entries.empty()) out += fmt::format("IRFs per palette entry: {}\n", entries);
  return out;
}

}  // namespace phasecast::precompute
