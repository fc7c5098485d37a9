#include "phasecast/core/package_summary.h"

#include "phasecast/core/basis.h"
#include "phasecast/core/hash.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

namespace phasecast::core {
namespace {

std::string human_bytes(std::uint64_t b) {
  if (b < 1024) return fmt::format("{} B", b);
  if (b < 1024 * 1024) return fmt::format("{:.1f} KiB", static_cast<double>(b) / 1024);
  return fmt::format("{:.2f} MiB", static_cast<double>(b) / (1024.0 * 1024.0));
}

// JSON has no NaN: unknown figures become null.
nlohmann::json number_or_null(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
}

// sigma_{r+1}/sigma_1, or NaN where sigma_{r+1} was not computed.
double sigma_ratio(const Eigen::VectorXf& sigma, int r) {
  return r >= 1 && r < sigma.size() && sigma[0] > 0 ? static_cast<double>(sigma[r] / sigma[0]) : std::nan("");
}

void summarize_appearance(const Appearance& a, PackageSummary& s) {
  for (Eigen::Index i = 0; i < a.rel_error.size(); ++i) s.error_a_curve.push_back(a.rel_error[i]);
  s.paper_rank_a = a.paper_rank;
  s.error_a_at_paper_rank = a.paper_rank > 0 && a.paper_rank <= a.rel_error.size()
                                ? static_cast<double>(a.rel_error[a.paper_rank - 1])
                                : std::nan("");
  s.sigma_ratio_a_at_rank = sigma_ratio(a.singular_values, s.rank_a);
  s.sigma_ratio_a_at_paper_rank = sigma_ratio(a.singular_values, a.paper_rank);
  s.singular_values_a.assign(a.singular_values.data(), a.singular_values.data() + a.singular_values.size());
  const auto& v = a.interpolant_parameters;
  if (is_affine_interpolant(a.interpolant) && v.size() >= 1) {
    s.interpolant = fmt::format("{} (k = {}, ridge {:g})", a.interpolant, v[0], a.nrbf_regularization);
  } else if (a.interpolant == "knn" && v.size() >= 1) {
    s.interpolant = fmt::format("knn (k = {})", v[0]);
  } else if (v.size() >= 2) {
    s.interpolant = fmt::format("nrbf (width scale {}, lambda {:g})", v[0], v[1]);
  } else {
    s.interpolant = a.interpolant;
  }
  s.transfer_weighting = a.transfer_weighting;
  s.transfer_rays = a.transfer_rays;
  s.transfer_bounces = a.transfer_bounces;
  s.held_out = a.held_out;
}

std::string percent_or_na(double ratio) {
  return std::isfinite(ratio) ? fmt::format("{:.3g}%", 100 * ratio)
                              : std::string("n/a (no sigma_{r+1} computed)");
}

// The error curve at a few ranks: 1, 2, 4, 8, ... and the paper's r_a.
std::string curve_text(const PackageSummary& s) {
  std::vector<std::string> points;
  const auto n = static_cast<int>(s.error_a_curve.size());
  for (int r = 1; r <= n; r = r < 4 ? r + 1 : r * 2) {
    if (r >= n - 1) break;  // N_a - 1 centred fields span the samples: 0 from there on
    points.push_back(fmt::format("{}: {:.3g}%", r, 100 * s.error_a_curve[static_cast<size_t>(r - 1)]));
  }
  return fmt::format("{}", fmt::join(points, ", "));
}

double nan_if_absent(const std::optional<float>& v) {
  return v ? *v : std::nan("");
}

// The held-out truth's lines of to_text().
std::string held_out_text(const PackageSummary& s, const HeldOutFigures& h) {
  std::string out;
  auto line = [&out]<class... Args>(fmt::format_string<Args...> f, Args&&... args) {
    out += "             " + fmt::format(f, std::forward<Args>(args)...) + "\n";
  };
  const auto nodes = static_cast<int>(h.nodes.size());
  line(
      "held-out truth ({} other nodes): error {:.3g}% = truncation {:.3g}% + interpolation {:.3g}% "
      "(in quadrature, of |M - M-bar|); {:.3g}% of |M|",
      nodes, 100 * h.total, 100 * h.truncation, 100 * h.interpolation, 100 * h.of_transfer);
  if (h.l2_total && h.l2_truncation)
    line(
        "held-out in the paper's relErr (relative l2 norm over those nodes): {:.3g}%, of which truncation "
        "{:.3g}%",
        100 * *h.l2_total, 100 * *h.l2_truncation);
  if (h.l2_total_spread && h.l2_truncation_spread)
    line("over resampled nodes (10th-90th percentile): {:.3g}-{:.3g}%, truncation {:.3g}-{:.3g}%",
         100 * h.l2_total_spread->p10, 100 * h.l2_total_spread->p90, 100 * h.l2_truncation_spread->p10,
         100 * h.l2_truncation_spread->p90);
  if (h.clusters_l2_truncation)
    line("the clusters' own truncation measured alike (relative l2 over {}): {:.3g}%",
         nodes < s.clusters ? fmt::format("{} of them, median of random draws", nodes)
                            : fmt::format("all {}{}", s.clusters,
                                          s.transfer_weighting == "equal" ? ": sigma_{r+1}/sigma_1" : ""),
         100 * *h.clusters_l2_truncation);
  if (h.l2_floor)
    line(
        "the least any rank-{} model about M-bar reaches at those nodes (sigma_{{r+1}}/sigma_1 of their "
        "M - M-bar): {:.3g}%",
        s.rank_a, 100 * *h.l2_floor);
  if (h.of_variation && h.l2_of_variation && h.l2_floor_of_variation)
    line(
        "of the nodes' own variation |M - their mean| (moves with no model): error {:.3g}%, relative l2 "
        "{:.3g}%; the least any rank-{} model reaches there, whatever its mean, {:.3g}%",
        100 * *h.of_variation, 100 * *h.l2_of_variation, s.rank_a, 100 * *h.l2_floor_of_variation);
  if (h.l2_of_variation_spread)
    line("of their own variation over resampled nodes (10th-90th percentile): relative l2 {:.3g}-{:.3g}%",
         100 * h.l2_of_variation_spread->p10, 100 * h.l2_of_variation_spread->p90);
  if (h.truncation_curve.size() > 0)
    line("held-out truncation by rank (Fig. 12 out of sample, relative l2): {}",
         held_out_curve_text(std::vector<double>(h.truncation_curve.begin(), h.truncation_curve.end()),
                             s.rank_a, s.paper_rank_a, nan_if_absent(h.clusters_l2_truncation)));
  return out;
}

// inspect --json's "held_out": the figures by name, null where not measured;
// the spreads as one list of (10th, 90th) pairs: l2 total, truncation, of the
// nodes' own variation.
nlohmann::json held_out_json(const HeldOutFigures& h) {
  std::vector<double> spread;
  for (const auto& p : {h.l2_total_spread, h.l2_truncation_spread, h.l2_of_variation_spread}) {
    if (!p) break;
    spread.insert(spread.end(), {p->p10, p->p90});
  }
  const auto optional = [](const std::optional<float>& v) { return number_or_null(nan_if_absent(v)); };
  return {{"nodes", h.nodes.size()},
          {"total", double{h.total}},
          {"truncation", double{h.truncation}},
          {"interpolation", double{h.interpolation}},
          {"of_transfer", double{h.of_transfer}},
          {"l2_total", optional(h.l2_total)},
          {"l2_truncation", optional(h.l2_truncation)},
          {"clusters_l2_truncation", optional(h.clusters_l2_truncation)},
          {"l2_floor", optional(h.l2_floor)},
          {"of_variation", optional(h.of_variation)},
          {"l2_of_variation", optional(h.l2_of_variation)},
          {"l2_floor_of_variation", optional(h.l2_floor_of_variation)},
          {"l2_spread", spread.empty() ? nlohmann::json() : nlohmann::json(spread)},
          {"l2_truncation_curve",
           h.truncation_curve.size() == 0
               ? nlohmann::json()
               : nlohmann::json(std::vector<double>(h.truncation_curve.begin(), h.truncation_curve.end()))}};
}

}  // namespace

std::string held_out_curve_text(const std::vector<double>& curve, int rank_a, int paper_rank_a,
                                double in_sample) {
  const auto K = static_cast<int>(curve.size());
  if (K == 0) return {};
  std::set<int> ranks{rank_a, paper_rank_a};
  for (int r = 1; r < K; r = r < 4 ? r + 1 : r * 2) ranks.insert(r);
  std::vector<std::string> points;
  for (int r : ranks) {
    if (r < 1 || r > K || (r == K && r != rank_a)) continue;  // "all K" reads rank K
    const std::string name = r == rank_a         ? fmt::format("r_a = {}", r)
                             : r == paper_rank_a ? fmt::format("the paper's r_a = {}", r)
                                                 : fmt::format("{}", r);
    points.push_back(fmt::format("{}: {:.3g}%", name, 100 * curve[static_cast<size_t>(r - 1)]));
  }
  std::string out = fmt::format("{}{}all {} directions of the clusters: {:.3g}%", fmt::join(points, ", "),
                                points.empty() ? "" : ", ", K, 100 * curve.back());
  if (!std::isfinite(in_sample)) return out;
  // Where the held-out states first fit as well as the clusters fit themselves at r_a.
  const auto reached = std::find_if(curve.begin(), curve.end(), [&](double e) { return e <= in_sample; });
  const std::string own =
      fmt::format("the clusters' own truncation at r_a measured alike ({:.3g}%)", 100 * in_sample);
  return out + (reached == curve.end()
                    ? fmt::format("; never as low as {}", own)
                    : fmt::format("; as low as {} from rank {}", own, 1 + (reached - curve.begin())));
}

namespace {

std::string fidelity_line(const PlaybackFidelity& f) {
  std::string out = fmt::format(
      "fidelity     playback vs the full simulation over {} random schedules of {} entries (seed {:.0f}): "
      "median "
      "NRMSE {:.3f}, 90th percentile {:.3f}; {} of {} moving segments within [0.67, 1.5] of the simulated "
      "motion, {} of {} switches within 2x the local motion\n",
      f.schedules, f.items, f.seed, f.median_nrmse, f.p90_nrmse, f.moving_within, f.moving, f.switches_within,
      f.switches);
  if (f.target_median_nrmse)
    out += fmt::format(
        "             sampled adaptively towards median NRMSE {:.3f}: {} after {} IRFs in {} rounds\n",
        *f.target_median_nrmse, f.target_met ? "met" : "not met", f.sampled_irfs, f.rounds);
  return out;
}

nlohmann::json fidelity_json(const PlaybackFidelity& f) {
  nlohmann::json j = {{"schedules", f.schedules},
                      {"items", f.items},
                      {"seed", f.seed},
                      {"median_nrmse", double{f.median_nrmse}},
                      {"p90_nrmse", double{f.p90_nrmse}},
                      {"moving_segments", f.moving},
                      {"moving_segments_within", f.moving_within},
                      {"switches", f.switches},
                      {"switches_within", f.switches_within}};
  if (f.target_median_nrmse)
    j["adaptive"] = {{"target_median_nrmse", double{*f.target_median_nrmse}},
                     {"target_met", f.target_met},
                     {"sampled_irfs", f.sampled_irfs},
                     {"rounds", f.rounds}};
  return j;
}

}  // namespace

PackageSummary summarize(const ScenePackage& p, const std::filesystem::path& file, int rank) {
  PackageSummary s;
  s.file = file.string();
  s.scene = p.attributes.scene;
  s.file_bytes = std::filesystem::file_size(file);
  s.content_hash = file_content_hash(file);
  s.points = p.mesh.points();
  for (auto d : p.mesh.deformable) s.deformable_points += d;
  s.triangles = p.mesh.triangle_count();
  s.state_nodes = p.portrait.nodes();
  s.irfs = p.portrait.irf_count();
  s.palette_entries = p.palette.size();
  s.palette = p.palette.names;
  s.irfs_per_entry.assign(static_cast<size_t>(s.palette_entries), 0);
  for (auto d : p.portrait.irf_palette) ++s.irfs_per_entry[static_cast<size_t>(d)];
  s.dt = p.attributes.dt;
  s.duration_s = s.dt * s.state_nodes;
  s.rank_u = p.rank_u();
  s.rank_a = p.rank_a();
  s.clusters = p.appearance ? p.appearance->clusters() : 0;
  s.chosen_rank = rank > 0 ? rank : s.rank_u;
  s.error_u_at_rank = displacement_error_at_rank(p, s.chosen_rank);
  const auto& sigma = p.reduction.singular_values;
  s.singular_values_u.assign(sigma.data(), sigma.data() + sigma.size());
  s.sigma_ratio_u_at_rank = sigma_ratio(sigma, s.chosen_rank);
  s.error_a_at_rank = std::nan("");
  if (p.appearance && s.rank_a > 0 && s.rank_a <= p.appearance->rel_error.size()) {
    s.error_a_at_rank = p.appearance->rel_error[s.rank_a - 1];
  }
  if (p.appearance) summarize_appearance(*p.appearance, s);
  s.fidelity = p.fidelity;
  for (const auto& part : basis_parts(p)) s.client_download_bytes += part.bytes.size();
  s.frame_state_bytes = reduced_state_bytes(p);
  s.full_vertex_frame_bytes = full_vertex_bytes(p);
  return s;
}

std::string to_text(const PackageSummary& s) {
  std::string out;
  auto line = [&out]<class... Args>(fmt::format_string<Args...> f, Args&&... args) {
    out += fmt::format(f, std::forward<Args>(args)...) + "\n";
  };
  line("package      {}", s.file);
  line("scene        {}", s.scene);
  line("file         {} ({}), content hash {:016x}", human_bytes(s.file_bytes), s.file_bytes, s.content_hash);
  line("mesh         S = {} scene points ({} deformable), F = {} triangles", s.points, s.deformable_points,
       s.triangles);
  line("portrait     N = {} state nodes ({:.1f} s at dt = {:.4g} s), n_irf = {} IRFs", s.state_nodes,
       s.duration_s, s.dt, s.irfs);
  std::vector<std::string> entries;
  for (size_t i = 0; i < s.palette.size(); ++i)
    entries.push_back(fmt::format("{}: {} ({} IRFs)", i, s.palette[i], s.irfs_per_entry[i]));
  line("palette      D = {}: {}", s.palette_entries, fmt::join(entries, ", "));
  line(
      "displacement r_u = {}, at rank {}: relative l2 error sigma_{{r+1}}/sigma_1 = {} (the paper's "
      "relErr, §2.3.1), Frobenius error = {:.3g}%",
      s.rank_u, s.chosen_rank, percent_or_na(s.sigma_ratio_u_at_rank), 100 * s.error_u_at_rank);
  if (s.rank_a > 0) {
    line(
        "appearance   r_a = {}, N_a = {} clusters, at r_a: relative l2 error sigma_{{r+1}}/sigma_1 = {} (the "
        "paper's relErr), Frobenius truncation error = {:.3g}% (on the clusters)",
        s.rank_a, s.clusters, percent_or_na(s.sigma_ratio_a_at_rank), 100 * s.error_a_at_rank);
    line("             Frobenius error curve (Fig. 12, red) at rank {}", curve_text(s));
    if (std::isfinite(s.error_a_at_paper_rank))
      line("             at the paper's r_a = {}: sigma_{{r+1}}/sigma_1 = {}, Frobenius {:.3g}%",
           s.paper_rank_a, percent_or_na(s.sigma_ratio_a_at_paper_rank), 100 * s.error_a_at_paper_rank);
    line("             interpolant {}, transfer fields weighted {}", s.interpolant, s.transfer_weighting);
    if (s.transfer_rays > 0)
      line("             transfer sampled with {} rays, {} interreflection bounces", s.transfer_rays,
           s.transfer_bounces);
    if (s.held_out) out += held_out_text(s, *s.held_out);
  } else {
    line("appearance   none");
  }
  if (s.fidelity) out += fidelity_line(*s.fidelity);
  line("thin client  downloads {} once; then {} B per frame (full vertex streaming: {} B, {:.0f}x more)",
       human_bytes(s.client_download_bytes), s.frame_state_bytes, s.full_vertex_frame_bytes,
       static_cast<double>(s.full_vertex_frame_bytes) / static_cast<double>(s.frame_state_bytes));
  return out;
}

nlohmann::json to_json(const PackageSummary& s) {
  return {
      {"file", s.file},
      {"scene", s.scene},
      {"file_bytes", s.file_bytes},
      {"content_hash", fmt::format("{:016x}", s.content_hash)},
      {"S", s.points},
      {"deformable_points", s.deformable_points},
      {"F", s.triangles},
      {"N", s.state_nodes},
      {"n_irf", s.irfs},
      {"D", s.palette_entries},
      {"palette", s.palette},
      {"irfs_per_entry", s.irfs_per_entry},
      {"dt", s.dt},
      {"duration_s", s.duration_s},
      {"r_u", s.rank_u},
      {"r_a", s.rank_a},
      {"N_a", s.clusters},
      {"rank", s.chosen_rank},
      {"rel_error_u", number_or_null(s.error_u_at_rank)},
      {"sigma_ratio_u", number_or_null(s.sigma_ratio_u_at_rank)},
      {"singular_values_u", s.singular_values_u},
      {"rel_error_a", number_or_null(s.error_a_at_rank)},
      {"rel_error_a_curve", s.error_a_curve},
      {"paper_rank_a", s.paper_rank_a},
      {"rel_error_a_at_paper_rank", number_or_null(s.error_a_at_paper_rank)},
      {"sigma_ratio_a", number_or_null(s.sigma_ratio_a_at_rank)},
      {"sigma_ratio_a_at_paper_rank", number_or_null(s.sigma_ratio_a_at_paper_rank)},
      {"singular_values_a", s.singular_values_a},
      {"interpolant", s.interpolant},
      {"transfer_weighting", s.transfer_weighting},
      {"transfer_rays", s.transfer_rays > 0 ? nlohmann::json(s.transfer_rays) : nlohmann::json()},
      {"transfer_bounces", s.transfer_rays > 0 ? nlohmann::json(s.transfer_bounces) : nlohmann::json()},
      {"held_out", s.held_out ? held_out_json(*s.held_out) : nlohmann::json()},
      {"fidelity", s.fidelity ? fidelity_json(*s.fidelity) : nlohmann::json()},
      {"client_download_bytes", s.client_download_bytes},
      {"frame_state_bytes", s.frame_state_bytes},
      {"full_vertex_frame_bytes", s.full_vertex_frame_bytes},
  };
}

}  // namespace phasecast::core
