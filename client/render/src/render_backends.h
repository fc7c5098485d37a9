#pragma once
// Factories of the concrete backends (osmesa_backend.cpp, egl_backend.cpp,
// window_backend.cpp); make_render_backend picks one by name.

#include "phasecast/client/render_backend.h"

namespace phasecast::client::detail {

std::unique_ptr<RenderBackend> make_osmesa_backend(int width, int height);
std::unique_ptr<RenderBackend> make_egl_backend();
std::unique_ptr<RenderBackend> make_window_backend(int width, int height);

}  // namespace phasecast::client::detail
