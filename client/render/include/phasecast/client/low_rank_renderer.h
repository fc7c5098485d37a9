#pragma once
// GPU evaluation of the low-rank model (§5.3). The bases go to shader storage
// buffers once (ranks are not capped by vertex-attribute limits); per frame
// only q_u, q_a, the support transform and the support-frame light change.
// The vertex program (shaders/low_rank.vert) computes x = x_bar + U_u q_u
// (eq. 7), the support transform for attached points, and the exit radiance
// (M_bar + U_a q_a) . L per colour channel (§4.2).

#include "phasecast/client/camera.h"
#include "phasecast/client/client_basis.h"
#include "phasecast/client/frame_state.h"
#include "phasecast/client/render_backend.h"
#include "phasecast/client/sh_light.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace phasecast::client {

// RGBA8, top row first, sRGB-encoded.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;
};

// What the vertex program computed for every scene point (transform feedback).
struct VertexDump {
  std::vector<float> positions;  // S x 3, world frame
  std::vector<float> radiance;   // S x 3, linear exit radiance
};

// Where the superposition runs. per_point_pass: once per scene point into a
// buffer (transform feedback), then the triangles are drawn from it;
// compute_pass: the same pass as a compute shader (llvmpipe runs those on
// all its threads, vertex programs on one); in_draw: inside the triangle
// draw, where a shared vertex may be evaluated again for each batch of
// triangles that uses it (92 % of a static mesh's rate on an NVIDIA H200,
// against 47 % for per_point_pass). The renderer's default is chosen per
// backend: compute_pass on llvmpipe, in_draw elsewhere.
enum class Evaluation { per_point_pass, in_draw, compute_pass };

// What is drawn behind the scene. none (the renderer's default): the plain
// clear colour kPlainBackground. ground: a floor at the rest mesh's lowest
// point (y up) that fades into the flat kBackdropBackground a few scene radii
// away (shaders/backdrop.frag): diffuse grey kGroundAlbedo lit by the light's
// irradiance for an up-facing normal, with a faint checker. It receives no
// transfer and leaves the scene's evaluation (evaluate(), --dump-vertices)
// as it is. phasecast-render draws it unless --backdrop off.
enum class Backdrop { none, ground };
// Clear colours: display values, written as they are (not sRGB-encoded).
inline constexpr std::array<float, 3> kPlainBackground{0.02f, 0.02f, 0.025f};
inline constexpr std::array<float, 3> kBackdropBackground{0.11f, 0.12f, 0.14f};
inline constexpr std::array<double, 3> kGroundAlbedo{0.3, 0.3, 0.3};

// How U_u and U_a are stored on the GPU: 32-bit floats, or 16-bit ones
// (--half: half the bytes per point, the error measured in
// docs/performance-client.md); everything else stays 32-bit.
enum class BasisPrecision { float32, float16 };

// How the per-point bases lie in GPU memory (shaders/bindings.glsl):
// point_rows, each point's values in one run (what a CPU thread evaluating
// a point reads best); point_tiles, tiles of 64 points with a point's value
// j beside its neighbours' (what a GPU warp of neighbouring points reads in
// few transactions). Same values either way. The renderer's default is
// chosen per backend: point_rows on llvmpipe (measured faster there,
// docs/performance-client.md), point_tiles elsewhere.
enum class BasisLayout { point_rows, point_tiles };
inline const char* basis_layout_name(BasisLayout layout) {
  return layout == BasisLayout::point_tiles ? "point tiles" : "point rows";
}

// How the compute passes (the light dot, and Evaluation::compute_pass) read
// the bases, the light-dotted transfer, q and the instances: as shader
// storage buffers, or as buffer textures over the same buffers (texelFetch).
// Same values and sums, so the same bits. llvmpipe (Mesa 22) loads from a
// storage buffer one lane at a time and fetches texels as one gather for all
// lanes: buffer textures are its default (frames 1.1-1.7 times faster there,
// docs/performance-client.md), storage buffers elsewhere. Scenes whose bases
// are bound in blocks of points always read storage buffers.
enum class ComputeReads { storage_buffers, buffer_textures };
inline const char* compute_reads_name(ComputeReads reads) {
  return reads == ComputeReads::buffer_textures ? "buffer textures" : "storage buffers";
}

class LowRankRenderer {
 public:
  // The backend's context must stay current and alive while the renderer lives.
  // On llvmpipe the first renderer of a process raises glibc's trim and mmap
  // thresholds (mallopt), process-wide: llvmpipe's per-draw buffers would
  // otherwise be faulted in anew every frame (docs/client.md).
  LowRankRenderer(RenderBackend& backend, const ClientBasis& basis, int width, int height,
                  BasisPrecision precision = BasisPrecision::float32,
                  std::optional<BasisLayout> layout = std::nullopt);  // none: the backend's default
  ~LowRankRenderer();
  LowRankRenderer(const LowRankRenderer&) = delete;
  LowRankRenderer& operator=(const LowRankRenderer&) = delete;

  void set_light(const ShLight& world_light);
  void set_camera(const Camera& camera);
  void set_exposure(float exposure);
  void set_evaluation(Evaluation evaluation);
  Evaluation evaluation() const;
  BasisLayout basis_layout() const;
  void set_compute_reads(ComputeReads reads);
  // What the compute passes read through (storage buffers for point blocks,
  // whatever was set).
  ComputeReads compute_reads() const;
  void set_backdrop(Backdrop backdrop);

  // Draws the frame into the offscreen framebuffer (and the window, if any).
  void draw(const FrameState& frame);
  // draw() then read back the pixels.
  Image render(const FrameState& frame);
  // Positions and radiance of every point via transform feedback.
  VertexDump evaluate(const FrameState& frame);

  // Many instances of the scene in one view: where each stands (instance
  // frame -> world: a rotation and a translation, RenderError otherwise), in
  // the order the calls below take their frames. Default: one instance where
  // the scene was made. The depth range and the ground take in all of them.
  void set_placements(std::vector<Eigen::Matrix4f> placements);
  std::size_t instances() const;
  // One frame per placement, all drawn by one instanced draw (§5.3 per instance).
  void draw(std::span<const FrameState> frames);
  Image render(std::span<const FrameState> frames);
  // Instance after instance: S points each.
  VertexDump evaluate(std::span<const FrameState> frames);

  // Benchmark reference: the same mesh drawn from static per-vertex data
  // (no low-rank evaluation), uploaded once by set_static_mesh: one mesh per
  // placed instance, as evaluate() returns them.
  void set_static_mesh(const VertexDump& vertices);
  void draw_static();
  // How often the transfer bases were dotted with the light (light_dot.comp):
  // once per change of light or support rotation, not once per frame.
  std::uint64_t light_dot_passes() const;
  // Blocks of points the passes bind at a time: 1 unless a basis (or all
  // instances' light-dotted transfer) is larger than one shader storage
  // block may span, GL_MAX_SHADER_STORAGE_BLOCK_SIZE or the lower
  // PHASECAST_MAX_STORAGE_BLOCK_BYTES from the environment.
  int point_blocks() const;
  // Bytes the GPU holds per scene point: the bases, the rest shape and
  // normals, and each instance's light-dotted transfer.
  std::size_t gpu_bytes_per_point() const;
  // Waits until the GPU finished (timing).
  void finish();
  Image read_pixels();

  // "OpenGL 4.5 (Core Profile) Mesa 22.3.6, llvmpipe (...)".
  std::string gl_description() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phasecast::client
