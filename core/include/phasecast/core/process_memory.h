#pragma once
// Resident memory of a process as the kernel counts it (/proc/<pid>/status):
// how the precompute stages and the benchmarks report their peak memory.

#include <sys/types.h>

namespace phasecast::core {

struct ResidentMemory {
  double current_mib = 0;  // VmRSS
  double peak_mib = 0;     // VmHWM: the largest VmRSS since the start or the last reset
};

// Of process `pid` (0: this one); zeros where /proc cannot be read.
ResidentMemory resident_memory(pid_t pid = 0);

// Sets this process's peak back to its current resident size (/proc/self/clear_refs),
// so that the next peak is that of the work that follows. False where the kernel refuses.
bool reset_peak_resident_memory();

}  // namespace phasecast::core
