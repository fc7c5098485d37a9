// A disk that stalls, for tests: LD_PRELOADed into phasecast-server, it holds
// every fsync/fdatasync while the file named by PHASECAST_TEST_HOLD_SYNC
// exists, and creates "<that name>.entered" when one is first held. A stalled
// disk is what made the tick late (issue 18: fdatasync ran inside the tick);
// holding the call until the test lets go makes that deterministic.

#include <dlfcn.h>
#include <fcntl.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

namespace {

void hold_while_asked() {
  const char* hold = std::getenv("PHASECAST_TEST_HOLD_SYNC");
  if (!hold || ::access(hold, F_OK) != 0) return;
  const std::string entered = std::string(hold) + ".entered";
  const int fd = ::open(entered.c_str(), O_WRONLY | O_CREAT, 0644);
  if (fd >= 0) ::close(fd);
  while (::access(hold, F_OK) == 0) ::usleep(10000);
}

template <class F>
F next(const char* name) {
  return reinterpret_cast<F>(::dlsym(RTLD_NEXT, name));
}

}  // namespace

extern "C" int fdatasync(int fd) {
  hold_while_asked();
  static const auto real = next<int (*)(int)>("fdatasync");
  return real(fd);
}

extern "C" int fsync(int fd) {
  hold_while_asked();
  static const auto real = next<int (*)(int)>("fsync");
  return real(fd);
}
