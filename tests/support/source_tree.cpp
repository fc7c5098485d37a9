#include "source_tree.h"

namespace phasecast::testing {

std::filesystem::path source_dir() {
  return PHASECAST_SOURCE_DIR;
}

std::filesystem::path scenes_dir() {
  return source_dir() / "scenes";
}

}  // namespace phasecast::testing
