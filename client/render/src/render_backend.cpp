#include "phasecast/client/render_backend.h"

#include "render_backends.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace phasecast::client {

std::vector<std::string> render_backend_names() {
  return {"osmesa", "egl", "window"};
}

std::unique_ptr<RenderBackend> make_render_backend(const std::string& name, int width, int height) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384) {
    throw RenderError(
        fmt::format("render size {}x{} is invalid (expected 1..16384 pixels per side)", width, height));
  }
  if (name == "osmesa") return detail::make_osmesa_backend(width, height);
  if (name == "egl") return detail::make_egl_backend();
  if (name == "window") return detail::make_window_backend(width, height);
  throw RenderError(fmt::format("render backend '{}' is unknown (expected one of {})", name,
                                fmt::join(render_backend_names(), ", ")));
}

}  // namespace phasecast::client
