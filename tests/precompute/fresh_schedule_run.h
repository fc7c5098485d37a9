#pragma once
// The adaptive run whose fresh schedules miss the target its guide meets
// (docs/sampling.md, step 3): the tiny toy, seed 5, one guide schedule.
// Round 1's 7 IRFs play the guide true but not the fresh ones, which join
// the guides; round 2 aims a chain at them and stops at 11 IRFs.

#include "source_tree.h"

#include <string>
#include <vector>

namespace phasecast::testing {

inline std::string fresh_schedule_scene() {
  return (scenes_dir() / "tiny" / "toy_dashboard.toml").string();
}

// run's options after the scene and -o; `fresh` is --fresh-schedules, `held_out` --held-out-schedules.
inline std::vector<std::string> fresh_schedule_options(const std::string& fresh,
                                                       const std::string& held_out) {
  return {"--chains",
          "3",
          "--irfs-per-chain",
          "1",
          "--seed",
          "5",
          "-j",
          "1",
          "--no-appearance",
          "--no-check",
          "--allow-missing-entries",
          "--until-fidelity",
          "0.15",
          "--budget-irfs",
          "30",
          "--guide-schedules",
          "1",
          "--fresh-schedules",
          fresh,
          "--held-out-schedules",
          held_out,
          "--fidelity-seed",
          "99"};
}

}  // namespace phasecast::testing
