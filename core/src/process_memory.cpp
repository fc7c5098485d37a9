#include "phasecast/core/process_memory.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <string>

namespace phasecast::core {

ResidentMemory resident_memory(pid_t pid) {
  std::ifstream in(pid == 0 ? std::string("/proc/self/status") : fmt::format("/proc/{}/status", pid));
  ResidentMemory m;
  std::string key;
  double kib = 0;
  while (in >> key) {
    if (key == "VmHWM:" && in >> kib) m.peak_mib = kib / 1024;
    if (key == "VmRSS:" && in >> kib) m.current_mib = kib / 1024;
  }
  return m;
}

bool reset_peak_resident_memory() {
  {
    std::ofstream clear("/proc/self/clear_refs");
    if (!(clear << "5" << std::flush)) return false;
  }
  const ResidentMemory m = resident_memory();
  return m.peak_mib > 0 && std::abs(m.peak_mib - m.current_mib) < 1.0;
}

}  // namespace phasecast::core
