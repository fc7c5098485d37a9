// GLFW window: for interactive viewing when a display exists. The renderer
// blits its framebuffer into the window and present() swaps.

#include "render_backends.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <fmt/format.h>

namespace phasecast::client::detail {
namespace {

class WindowBackend final : public RenderBackend {
 public:
  WindowBackend(int width, int height) {
    if (!glfwInit()) {
      const char* why = nullptr;
      glfwGetError(&why);
      throw RenderError(
          fmt::format("window backend: GLFW could not start ({}); use --backend osmesa or egl "
                      "on machines without a display",
                      why ? why : "no display"));
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    window_ = glfwCreateWindow(width, height, "phasecast-render", nullptr, nullptr);
    if (!window_) {
      glfwTerminate();
      throw RenderError("window backend: GLFW could not open a window with a GL 4.5 core context");
    }
    glfwMakeContextCurrent(window_);
    glfwSwapInterval(0);
  }
  ~WindowBackend() override {
    glfwDestroyWindow(window_);
    glfwTerminate();
  }
  WindowBackend(const WindowBackend&) = delete;
  WindowBackend& operator=(const WindowBackend&) = delete;

  std::string name() const override { return "window"; }
  void* get_proc_address(const char* function) override {
    return reinterpret_cast<void*>(glfwGetProcAddress(function));
  }
  void present() override {
    glfwSwapBuffers(window_);
    glfwPollEvents();
  }
  bool shows_frames() const override { return true; }
  bool open() const override { return !glfwWindowShouldClose(window_); }

 private:
  GLFWwindow* window_ = nullptr;
};

}  // namespace

std::unique_ptr<RenderBackend> make_window_backend(int width, int height) {
  return std::make_unique<WindowBackend>(width, height);
}

}  // namespace phasecast::client::detail
