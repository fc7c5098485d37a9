// The appearance stage's options from the user's choices, the scene and the defaults.

#include "phasecast/precompute/pipeline/stages.h"

#include "phasecast/precompute/distributed/ranks.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <initializer_list>
#include <stdexcept>
#include <utility>

#include <unistd.h>  // access(): is the folder of --save-transfers writable

namespace phasecast::precompute {
namespace {

// The value of `flag` named `value`; a one-line error listing the names otherwise.
template <class Choice>
Choice named_choice(const char* flag, const std::string& value,
                    std::initializer_list<std::pair<const char*, Choice>> names) {
  std::vector<std::string> listed;
  for (const auto& [name, choice] : names) {
    if (value == name) return choice;
    listed.emplace_back(name);
  }
  const std::string last = listed.back();
  listed.pop_back();
  throw std::invalid_argument(
      fmt::format("{} '{}': expected {} or {}", flag, value, fmt::join(listed, ", "), last));
}

}  // namespace

void check_save_transfers(const AppearanceChoices& a,
                          const std::vector<std::filesystem::path>& inputs_and_outputs) {
  if (a.save_transfers.empty()) return;
  if (a.skip)
    throw std::invalid_argument(
        "appearance: --save-transfers saves the appearance stage's transfers: drop --no-appearance");
  const std::filesystem::path file = std::filesystem::absolute(a.save_transfers);
  std::error_code ec;
  const auto expected = [&a](const std::string& what) {
    return std::invalid_argument(
        fmt::format("appearance: --save-transfers '{}': expected {}", a.save_transfers.string(), what));
  };
  if (!std::filesystem::is_directory(file.parent_path(), ec))
    throw expected(fmt::format("a file in an existing folder ({} is not one)", file.parent_path().string()));
  if (std::filesystem::is_directory(file, ec)) throw expected("a file, not a folder");
  if (::access(file.parent_path().c_str(), W_OK) != 0)
    throw expected(
        fmt::format("a file in a folder this user can write ({} is not)", file.parent_path().string()));
  for (const auto& other : inputs_and_outputs) {
    // The transfers file is renamed over its path: it must not replace the orbit store or the package.
    if (std::filesystem::weakly_canonical(file, ec) == std::filesystem::weakly_canonical(other, ec))
      throw expected(fmt::format("a file other than the orbit store and the package ({})", other.string()));
  }
}

AppearanceStageOptions appearance_stage_options(const Scene& scene, const AppearanceChoices& a) {
  auto s = a.stage;
  const auto& d = scene.appearance;
  s.clusters = a.clusters.value_or(d.clusters > 0 ? d.clusters : kDefaultClusters);
  s.held_out = a.held_out.value_or(d.held_out > 0 ? d.held_out : kDefaultHeldOut);
  s.transfer.rays = a.rays.value_or(d.rays > 0 ? d.rays : kDefaultRays);
  s.appearance.reduction.eps_a = a.eps_a.value_or(d.eps_a > 0 ? d.eps_a : kDefaultEpsA);
  s.appearance.interpolant =
      named_choice<InterpolantChoice>("--interpolant", a.interpolant,
                                      {{"best", InterpolantChoice::best},
                                       {"nrbf", InterpolantChoice::nrbf},
                                       {"knn", InterpolantChoice::knn},
                                       {"affine-knn", InterpolantChoice::affine_knn},
                                       {"affine-knn-slope", InterpolantChoice::affine_knn_slope}});
  s.appearance.weighting = named_choice<WeightingChoice>("--transfer-weighting", a.weighting,
                                                         {{"best", WeightingChoice::best},
                                                          {"equal", WeightingChoice::equal},
                                                          {"cluster-size", WeightingChoice::cluster_size}});
  s.paper_rank = d.paper_rank_a;
  s.transfer.point_albedo = scene_point_albedo(scene);
  check_appearance_stage_options(s);
  if (!a.save_transfers.empty()) {
    s.keep_transfers = [path = a.save_transfers.string()](const StageTransfers& t) {
      if (Ranks::world().rank() != 0) return;  // every rank holds them all; one writes
      try {
        write_stage_transfers(t, path);
        fmt::print(stderr, "appearance: wrote {} ({} transfers of {} scene points)\n", path, t.nodes.size(),
                   t.rest_positions.rows());
      } catch (const std::exception& e) {
        // A full disk must not cost the package the transfers were computed for.
        fmt::print(stderr, "appearance: --save-transfers: {}; the package is made without it\n", e.what());
      }
    };
  }
  return s;
}

}  // namespace phasecast::precompute
