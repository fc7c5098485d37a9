// OSMesa: a GL 4.5 core context rendered by llvmpipe on the CPU, with no
// display and no GPU (Mesa 22.3 supports core profiles through
// OSMesaCreateContextAttribs).

#include "render_backends.h"

#include <GL/osmesa.h>
#include <fmt/format.h>

#include <vector>

namespace phasecast::client::detail {
namespace {

class OsmesaBackend final : public RenderBackend {
 public:
  OsmesaBackend(int width, int height) {
    const int attributes[] = {OSMESA_FORMAT,
                              OSMESA_RGBA,
                              OSMESA_DEPTH_BITS,
                              24,
                              OSMESA_PROFILE,
                              OSMESA_CORE_PROFILE,
                              OSMESA_CONTEXT_MAJOR_VERSION,
                              4,
                              OSMESA_CONTEXT_MINOR_VERSION,
                              5,
                              0};
    context_ = OSMesaCreateContextAttribs(attributes, nullptr);
    if (!context_) {
      throw RenderError("osmesa backend: OSMesaCreateContextAttribs could not create a GL 4.5 core context");
    }
    // The renderer draws into its own framebuffer object; this buffer only
    // makes the context current, so it can be tiny.
    (void)width;
    (void)height;
    buffer_.assign(4 * 4 * 4, 0);
    if (!OSMesaMakeCurrent(context_, buffer_.data(), GL_UNSIGNED_BYTE, 4, 4)) {
      OSMesaDestroyContext(context_);
      throw RenderError("osmesa backend: OSMesaMakeCurrent failed");
    }
  }
  ~OsmesaBackend() override { OSMesaDestroyContext(context_); }
  OsmesaBackend(const OsmesaBackend&) = delete;
  OsmesaBackend& operator=(const OsmesaBackend&) = delete;

  std::string name() const override { return "osmesa"; }
  void* get_proc_address(const char* function) override {
    return reinterpret_cast<void*>(OSMesaGetProcAddress(function));
  }

 private:
  OSMesaContext context_ = nullptr;
  std::vector<unsigned char> buffer_;
};

}  // namespace

std::unique_ptr<RenderBackend> make_osmesa_backend(int width, int height) {
  return std::make_unique<OsmesaBackend>(width, height);
}

}  // namespace phasecast::client::detail
