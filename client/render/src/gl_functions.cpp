#include "gl_functions.h"

#include <fmt/format.h>

namespace phasecast::client::detail {

GlFunctions load_gl_functions(RenderBackend& backend) {
  GlFunctions gl;
#define PHASECAST_GL_LOAD(type, fn)                                                                         \
  gl.fn = reinterpret_cast<type>(backend.get_proc_address(#fn));                                            \
  if (!gl.fn) {                                                                                             \
    throw RenderError(fmt::format(                                                                          \
        "{} backend: OpenGL entry point {} is missing (need a GL 4.5 core context)", backend.name(), #fn)); \
  }
  PHASECAST_GL_FUNCTIONS(PHASECAST_GL_LOAD)
#undef PHASECAST_GL_LOAD
  return gl;
}

}  // namespace phasecast::client::detail
