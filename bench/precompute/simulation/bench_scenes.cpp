#include "bench_scenes.h"

namespace phasecast::bench {

std::filesystem::path scenes_dir() {
  return PHASECAST_SCENES_DIR;
}

}  // namespace phasecast::bench
