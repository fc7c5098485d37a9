// The stages of `phasecast-precompute run` called as a library: the reports
// they return describe the store and the package they wrote, and the report
// text says what the tool prints, with no tool run.

#include "phasecast/precompute/pipeline/stages.h"
#include "phasecast/core/package.h"
#include "phasecast/precompute/package/package_builder.h"
#include "phasecast/precompute/pipeline/report_text.h"
#include "run_tool.h"  // scratch_dir
#include "scene_files.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace phasecast::precompute {
namespace {

using ::testing::HasSubstr;

TEST(PipelineStages, ReportsDescribeWhatTheStagesWrote) {
  const auto dir = testing::scratch_dir("pipeline_stages");
  const Scene scene = load_scene_file(testing::tiny_scene_path());
  SampleStageOptions sample;
  sample.sampling.chains = 2;
  sample.sampling.irfs_per_chain = 3;
  sample.sampling.seed = 4;
  const auto orbits = dir / "orbits.h5";
  const SampleReport sampled = run_sample_stage(scene, sample, orbits);
  EXPECT_TRUE(sampled.writer);
  EXPECT_EQ(sampled.irfs, 6);
  EXPECT_EQ(sampled.frames, read_orbit_index(orbits).support.rows());
  ASSERT_TRUE(sampled.contact);  // the tiny cloth collides with itself
  EXPECT_EQ(sampled.contact->frames, sampled.frames);
  EXPECT_THAT(sample_report_text(sampled),
              HasSubstr(fmt::format("wrote {} (6 IRFs, {} state nodes; chain stores merged in ",
                                    orbits.string(), sampled.frames)));
  EXPECT_THAT(sample_report_text(sampled), HasSubstr("\ncontact: "));

  ReduceStageOptions reduce;
  reduce.reduction.max_rank = 20;
  AppearanceChoices appearance;
  appearance.clusters = 4;
  appearance.held_out = 6;
  appearance.rays = 64;
  const auto package = dir / "tiny.h5";
  const ReduceReport reduced = run_reduce_stage(scene, reduce, appearance, orbits, package);
  const core::ScenePackage written = core::read_package(package);
  EXPECT_EQ(reduced.package.rank_u(), written.rank_u());
  EXPECT_EQ(reduced.package.rank_a(), written.rank_a());
  EXPECT_EQ(reduced.package.portrait.irf_count() + reduced.dropped_short + reduced.dropped_dead_end, 6);
  EXPECT_EQ(static_cast<int>(reduced.dropped.size()), reduced.dropped_short + reduced.dropped_dead_end);
  ASSERT_TRUE(reduced.appearance);
  EXPECT_EQ(reduced.appearance->stage.clusters.representatives, written.appearance->cluster_nodes);
  ASSERT_TRUE(written.appearance->held_out);
  const std::string text = reduce_report_text(reduced);
  EXPECT_THAT(text, HasSubstr(fmt::format("appearance: N_a = 4 clusters, {} scene points, r_a = {} ",
                                          written.mesh.points(), written.rank_a())));
  EXPECT_THAT(text, HasSubstr(fmt::format("appearance: held-out error over {} nodes {:.4f} = truncation ",
                                          written.appearance->held_out->nodes.size(),
                                          written.appearance->held_out->total)));
  EXPECT_THAT(text, HasSubstr(fmt::format("wrote {}: N = {} state nodes, {} IRFs", package.string(),
                                          written.portrait.nodes(), written.portrait.irf_count())));
  EXPECT_EQ(text.back(), '\n');
}

// Without the appearance stage the report has none and says only what was written.
TEST(PipelineStages, ReduceTextWithoutAppearanceIsTheWrittenLine) {
  ReduceReport r;
  r.writer = true;
  r.package_path = "/tmp/plate.h5";
  r.package = testing::make_plate_package();
  r.package.appearance.reset();
  r.package.portrait.q_a.resize(r.package.portrait.nodes(), 0);
  r.dropped_short = 1;
  r.dropped_dead_end = 2;
  EXPECT_EQ(reduce_report_text(r),
            fmt::format("wrote /tmp/plate.h5: N = {} state nodes, {} IRFs (1 short and 2 dead ends dropped), "
                        "r_u = {} (error {:.4f}), r_a = 0, beta = {:.4g}\n",
                        r.package.portrait.nodes(), r.package.portrait.irf_count(), r.package.rank_u(),
                        core::displacement_error_at_rank(r.package, r.package.rank_u()),
                        r.package.attributes.beta));
}

// The held-out figures the appearance text prints are the package's, by name.
TEST(PipelineStages, AppearanceTextPrintsTheNamedHeldOutFigures) {
  core::ScenePackage p = testing::make_plate_package();
  core::HeldOutFigures& h = p.appearance->held_out.emplace();
  h.nodes = {1, 2, 3};
  h.total = 0.5f;
  h.truncation = 0.3f;
  h.interpolation = 0.4f;
  h.of_transfer = 0.05f;
  h.l2_total = 0.45f;
  h.l2_truncation = 0.25f;
  h.clusters_l2_truncation = 0.2f;
  h.l2_floor = 0.1f;
  h.l2_total_spread = core::Percentiles{0.4f, 0.6f};
  h.l2_truncation_spread = core::Percentiles{0.2f, 0.3f};
  const std::string text = appearance_report_text(*p.appearance, {});
  EXPECT_THAT(text,
              HasSubstr("appearance: held-out error over 3 nodes 0.5000 = truncation 0.3000 + "
                        "interpolation 0.4000 (in quadrature, relative to |M - M-bar|); 0.0500 of |M|; "
                        "relative l2 norm (the paper's relErr) 0.4500, truncation alone 0.2500, the "
                        "clusters' own truncation over as many of them (all, if fewer) 0.2000, the least "
                        "any rank-"));
  EXPECT_THAT(text, HasSubstr("relative l2 0.4000-0.6000, truncation alone 0.2000-0.3000\n"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr("own variation |M - their mean|")));  // not measured
}

}  // namespace
}  // namespace phasecast::precompute
