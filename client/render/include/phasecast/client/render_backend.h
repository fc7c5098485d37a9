#pragma once
// Where the client's OpenGL 4.5 core context comes from. One interface,
// chosen by name at run time: "osmesa" (default; headless, CPU llvmpipe,
// works in CI), "egl" (headless, GPU when the machine has one), "window"
// (GLFW, needs a display). The renderer draws into its own framebuffer object,
// so every backend only has to provide a current context.

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::client {

// Thrown for every rendering failure (no context, shader errors, bad sizes);
// one line naming the backend or input and what was expected.
class RenderError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class RenderBackend {
 public:
  virtual ~RenderBackend() = default;
  virtual std::string name() const = 0;
  // Entry point of the current context, or nullptr.
  virtual void* get_proc_address(const char* function) = 0;
  // Shows the finished frame (window backend); headless backends do nothing.
  virtual void present() {}
  // True when present() shows frames on a screen.
  virtual bool shows_frames() const { return false; }
  // False once a window was closed by the user; headless backends stay open.
  virtual bool open() const { return true; }
};

// Names accepted by make_render_backend, default first.
std::vector<std::string> render_backend_names();

// Creates a context of `width` x `height` pixels (the window backend opens a
// window of that size). Throws RenderError for unknown names, e.g.
// "render backend 'vulkan' is unknown (expected one of osmesa, egl, window)",
// and when the backend cannot give a GL 4.5 core context.
std::unique_ptr<RenderBackend> make_render_backend(const std::string& name, int width, int height);

}  // namespace phasecast::client
