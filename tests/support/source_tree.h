#pragma once
// The checkout's folders that tests read: scene files, committed packages,
// golden images. The checkout's path is compiled into source_tree.cpp alone,
// so no other test object depends on where the clone lives and a compiler
// cache shares them between clones (CI builds a fresh one).

#include <filesystem>

namespace phasecast::testing {

// The checkout's root (CMake's PROJECT_SOURCE_DIR).
std::filesystem::path source_dir();

// source_dir() / "scenes".
std::filesystem::path scenes_dir();

}  // namespace phasecast::testing
