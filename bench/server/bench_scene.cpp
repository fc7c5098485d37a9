#include "bench_scene.h"

#include "run_tool.h"
#include "synthetic_package.h"

namespace phasecast::bench {

std::shared_ptr<const core::ScenePackage> cloth_ranks_scene() {
  static const auto scene = [] {
    testing::PlateOptions o;
    o.grid = 58;            // 3364 plate points
    o.rank_u = 30;          // r_u of the paper's cloth
    o.irfs_per_entry = 57;  // 171 IRFs
    o.irf_length = 47;      // N = 8037 state nodes
    o.clusters = 13;        // centred: r_a <= 12
    o.eps_a = 1e-7;
    return std::make_shared<const core::ScenePackage>(testing::make_plate_package(o));
  }();
  return scene;
}

const std::filesystem::path& cloth_ranks_package_file() {
  static const auto path = [] {
    const auto p = testing::scratch_dir("bench_server") / "cloth_ranks.h5";
    core::write_package(*cloth_ranks_scene(), p);
    return p;
  }();
  return path;
}

}  // namespace phasecast::bench
