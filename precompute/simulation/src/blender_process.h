#pragma once
// One headless Blender process running the driver (blender/driver.py) on a
// .blend file, spoken to over a socket on the child's descriptor 3. Blender's
// own output goes to a private log whose last lines every failure quotes.

#include "phasecast/precompute/simulation/simulator.h"

#include <sys/types.h>

#include <cstddef>
#include <filesystem>
#include <string>

namespace phasecast::precompute::detail {

class BlenderProcess {
 public:
  // Starts `blender -b BLEND --python-expr DRIVER -- MODE CONFIG`; the
  // executable is $PHASECAST_BLENDER or `blender` on the PATH.
  BlenderProcess(const std::filesystem::path& blend, const std::string& mode, const std::string& config,
                 double timeout_seconds);
  ~BlenderProcess();
  BlenderProcess(const BlenderProcess&) = delete;
  BlenderProcess& operator=(const BlenderProcess&) = delete;

  // The next line of the driver; its {"error": ...} and Blender's death or
  // silence beyond the timeout are SimulationErrors naming the .blend.
  std::string read_line();
  void read_exact(void* out, std::size_t bytes);
  void write(const std::string& text);

  // What Blender printed last, joined into one line.
  std::string last_lines(int count) const;

 private:
  [[noreturn]] void fail(const std::string& what);
  void wait_readable();
  std::string exit_description();

  std::filesystem::path blend_;
  double timeout_;
  pid_t pid_ = -1;
  int channel_ = -1;
  int log_ = -1;
  std::string buffer_;  // read past the last line
};

// The Blender executable this process would run; a SimulationError saying
// how to install it when there is none.
std::filesystem::path blender_executable();

}  // namespace phasecast::precompute::detail
