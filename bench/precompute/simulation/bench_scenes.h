#pragma once
// The checkout's scenes folder, compiled into bench_scenes.cpp alone so that
// the benchmark objects do not depend on where the clone lives (a compiler
// cache shares them between clones; tests/support/source_tree.h does the same).

#include <filesystem>

namespace phasecast::bench {

std::filesystem::path scenes_dir();

}  // namespace phasecast::bench
