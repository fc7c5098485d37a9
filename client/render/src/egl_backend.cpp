// EGL: a headless GL 4.5 core context without a window. On a GPU machine it
// takes the first EGL device (EGL_EXT_platform_device); elsewhere Mesa's
// surfaceless platform (llvmpipe), so the backend also runs in CI.

#include "render_backends.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <fmt/format.h>

#include <cstring>
#include <string>

namespace phasecast::client::detail {
namespace {

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const std::string all = std::string(" ") + list + " ";
  return all.find(std::string(" ") + name + " ") != std::string::npos;
}

// First device display if the driver offers devices, else Mesa surfaceless.
EGLDisplay open_display() {
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  auto get_platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (!get_platform_display) return eglGetDisplay(EGL_DEFAULT_DISPLAY);
  if (has_extension(client_extensions, "EGL_EXT_platform_device")) {
    auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    EGLDeviceEXT devices[8];
    EGLint count = 0;
    if (query_devices && query_devices(8, devices, &count) && count > 0) {
      for (EGLint i = 0; i < count; ++i) {
        EGLDisplay d = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
        if (d != EGL_NO_DISPLAY && eglInitialize(d, nullptr, nullptr)) return d;
      }
    }
  }
  if (has_extension(client_extensions, "EGL_MESA_platform_surfaceless")) {
    return get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  }
  return eglGetDisplay(EGL_DEFAULT_DISPLAY);
}

class EglBackend final : public RenderBackend {
 public:
  EglBackend() {
    display_ = open_display();
    if (display_ == EGL_NO_DISPLAY || !eglInitialize(display_, nullptr, nullptr)) {
      throw RenderError(
          fmt::format("egl backend: no EGL display could be initialised (EGL error 0x{:x})", eglGetError()));
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
      throw RenderError("egl backend: the EGL display does not offer desktop OpenGL");
    }
    const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint configs = 0;
    eglChooseConfig(display_, config_attributes, &config, 1, &configs);
    const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION,
                                         4,
                                         EGL_CONTEXT_MINOR_VERSION,
                                         5,
                                         EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                         EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                         EGL_NONE};
    context_ = eglCreateContext(display_, configs > 0 ? config : EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT,
                                context_attributes);
    if (context_ == EGL_NO_CONTEXT) {
      eglTerminate(display_);
      throw RenderError(fmt::format("egl backend: could not create a GL 4.5 core context (EGL error 0x{:x})",
                                    eglGetError()));
    }
    if (!eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_)) {
      eglDestroyContext(display_, context_);
      eglTerminate(display_);
      throw RenderError(
          "egl backend: the context cannot be made current without a surface "
          "(EGL_KHR_surfaceless_context missing)");
    }
  }
  ~EglBackend() override {
    eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display_, context_);
    eglTerminate(display_);
  }
  EglBackend(const EglBackend&) = delete;
  EglBackend& operator=(const EglBackend&) = delete;

  std::string name() const override { return "egl"; }
  void* get_proc_address(const char* function) override {
    return reinterpret_cast<void*>(eglGetProcAddress(function));
  }

 private:
  EGLDisplay display_ = EGL_NO_DISPLAY;
  EGLContext context_ = EGL_NO_CONTEXT;
};

}  // namespace

std::unique_ptr<RenderBackend> make_egl_backend() {
  return std::make_unique<EglBackend>();
}

}  // namespace phasecast::client::detail
