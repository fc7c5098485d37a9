#pragma once
// Threads that may wait a little so that the tick does not: request serving
// and the recording writer run at a nice value above the process's, so on a
// busy machine the tick thread wins the CPU. Raising one's own nice value
// needs no privilege.

#include <sys/resource.h>
#include <unistd.h>

namespace phasecast::server {

inline void yield_to_the_tick() {
  setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), getpriority(PRIO_PROCESS, 0) + 5);
}

}  // namespace phasecast::server
