#include "phasecast/client/low_rank_renderer.h"

#include "bindings.glsl"
#include "gl_functions.h"
#include "gl_handles.h"
#include "gl_program.h"
#include "ground_plane.h"
#include "phasecast/client/embedded_shaders.h"

#include <fmt/format.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <string_view>
#include <utility>

#if defined(__GLIBC__)  // set by <cstdlib> above on glibc systems
#include <malloc.h>
#endif

namespace phasecast::client {

using detail::Buffer;
using detail::Framebuffer;
using detail::GlFunctions;
using detail::GlProgram;
using detail::GroundPlane;
using detail::Renderbuffer;
using detail::Texture;
using detail::VertexArray;

namespace {

// Shader storage bindings, named as shaders/bindings.glsl numbers them.
enum Binding : GLuint {
  kMeanShape = PHASECAST_BINDING_MEAN_SHAPE,
  kDisplacementBasis = PHASECAST_BINDING_DISPLACEMENT_BASIS,
  kMeanTransfer = PHASECAST_BINDING_MEAN_TRANSFER,
  kTransferBasis = PHASECAST_BINDING_TRANSFER_BASIS,
  kPointFlags = PHASECAST_BINDING_POINT_FLAGS,
  kRestNormals = PHASECAST_BINDING_REST_NORMALS,
  kReduced = PHASECAST_BINDING_REDUCED,
  kMeanDotted = PHASECAST_BINDING_MEAN_DOTTED,
  kBasisDotted = PHASECAST_BINDING_BASIS_DOTTED,
  kInstances = PHASECAST_BINDING_INSTANCES,
  kEvaluated = PHASECAST_BINDING_EVALUATED,
  kBindingCount = PHASECAST_BINDING_COUNT
};

// llvmpipe mallocs its vertex buffers for each draw and frees them after it.
// glibc gives the freed top of the heap back to the kernel once it exceeds a
// trim threshold (128 KB until glibc raises it), so every frame faulted the
// same pages in again: 16 demo cloths drew in 58 ms instead of 17 (270 k page
// faults in 7 s, docs/performance-client.md). A process that renders on
// llvmpipe keeps up to kKeptHeap of freed heap instead, and takes blocks up
// to kHeapBlock from the heap rather than mapping each one (setting either
// threshold stops glibc from adjusting the other). Process-wide, once, and
// only on llvmpipe (docs/client.md).
constexpr int kKeptHeap = 256 << 20;
constexpr int kHeapBlock = 32 << 20;  // glibc's largest mmap threshold on 64-bit

void keep_freed_heap() {
#if defined(__GLIBC__)
  // Once per process, each on its own (a refused one leaves the other set).
  static const bool kept = [] {
    mallopt(M_TRIM_THRESHOLD, kKeptHeap);
    mallopt(M_MMAP_THRESHOLD, kHeapBlock);
    return true;
  }();
  (void)kept;
#endif
}

// Row-major rows x cols -> rows x (4 ceil(cols / 4)), zero-padded, so the
// shader reads each row in vec4 blocks.
std::vector<float> pad_columns(const std::vector<float>& m, int cols) {
  const auto c = static_cast<std::size_t>(cols), padded = 4 * ((c + 3) / 4);
  if (c == 0 || c == padded) return m;
  const std::size_t rows = m.size() / c;
  std::vector<float> out(rows * padded, 0.0f);
  for (std::size_t r = 0; r < rows; ++r) std::copy_n(&m[r * c], c, &out[r * padded]);
  return out;
}

// Per-point rows of vec4s (each point's W vec4s in a row) in tiles of
// `tile` points, vec4 j of a tile's points side by side (bindings.glsl,
// PHASECAST_TILED; tile 1: the rows as they are); `stride_points` points,
// the last zero-padded.
std::vector<float> tile_points(const std::vector<float>& m, int points, int stride_points, std::size_t tile) {
  if (m.empty()) return m;
  const auto P = static_cast<std::size_t>(points), W = m.size() / (4 * P);
  std::vector<float> out(static_cast<std::size_t>(stride_points) * W * 4, 0.0f);
  for (std::size_t v = 0; v < P; ++v)
    for (std::size_t j = 0; j < W; ++j)
      std::copy_n(&m[4 * (v * W + j)], 4, &out[4 * (v / tile * (tile * W) + j * tile + v % tile)]);
  return out;
}

// IEEE binary16 values of a float matrix (--half); the shaders read them in
// pairs with unpackHalf2x16.
std::vector<std::uint16_t> to_half(const std::vector<float>& m) {
  std::vector<std::uint16_t> out(m.size());
  for (std::size_t i = 0; i < m.size(); ++i) out[i] = Eigen::half(m[i]).x;
  return out;
}

// Bit 0: deformable, bit 1: attached (shaders/low_rank.vert).
std::vector<std::uint32_t> point_flags(const ClientBasis& basis) {
  std::vector<std::uint32_t> flags(static_cast<std::size_t>(basis.points));
  for (std::size_t v = 0; v < flags.size(); ++v) {
    flags[v] = (basis.deformable[v] ? 1u : 0u) | (basis.attached[v] ? 2u : 0u);
  }
  return flags;
}

// Floats per instance in the Instances buffer (shaders/low_rank_eval.glsl):
// placement and support (column-major mat4s), 24 vec4s of light, then the
// light-dotted copy its points read.
constexpr std::size_t kInstanceFloats = 4 * PHASECAST_INSTANCE_VEC4S;
constexpr std::size_t kDottedCopyFloat = 16 + 16 + 96;  // where the dotted copy's number goes
static_assert(kInstanceFloats == kDottedCopyFloat + 4);
using Lights = std::array<float, 96>;  // an instance's packed lights (instance_lights)

// Support transform (3x4 row-major, support -> world) as a 4x4 for GLSL.
Eigen::Matrix4f support_matrix(const FrameState& f) {
  Eigen::Matrix4f support = Eigen::Matrix4f::Identity();
  if (f.support.size() == 12) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 4; ++j) support(i, j) = f.support[static_cast<std::size_t>(4 * i + j)];
    }
  }
  return support;
}

// Interleaved position, radiance: 6 floats per point.
std::vector<float> interleave(const VertexDump& d, int points) {
  std::vector<float> interleaved;
  interleaved.reserve(2 * d.positions.size());
  for (std::size_t v = 0; v < static_cast<std::size_t>(points); ++v) {
    interleaved.insert(interleaved.end(), &d.positions[3 * v], &d.positions[3 * v + 3]);
    interleaved.insert(interleaved.end(), &d.radiance[3 * v], &d.radiance[3 * v + 3]);
  }
  return interleaved;
}

VertexDump deinterleave(const std::vector<float>& captured, std::size_t points) {
  VertexDump dump;
  dump.positions.reserve(3 * points);
  dump.radiance.reserve(3 * points);
  for (std::size_t v = 0; v < points; ++v) {
    dump.positions.insert(dump.positions.end(), &captured[6 * v], &captured[6 * v + 3]);
    dump.radiance.insert(dump.radiance.end(), &captured[6 * v + 3], &captured[6 * v + 6]);
  }
  return dump;
}

// GL reads rows bottom-up; Image holds them top row first.
void copy_rows_flipped(const std::vector<std::uint8_t>& bottom_up, Image& image) {
  const auto row = static_cast<std::size_t>(4 * image.width);
  const auto height = static_cast<std::size_t>(image.height);
  for (std::size_t y = 0; y < height; ++y) {
    std::memcpy(image.rgba.data() + y * row, bottom_up.data() + (height - 1 - y) * row, row);
  }
}

template <class T>
GLsizeiptr byte_size(const std::vector<T>& v) {
  return static_cast<GLsizeiptr>(v.size() * sizeof(T));
}

// Points per block are a multiple of this, so every block's first byte in
// every per-point buffer is 256-byte aligned (4 bytes per point and up).
constexpr int kBlockAlign = 64;
static_assert(kBlockAlign % PHASECAST_POINT_TILE == 0, "a block of points starts on a tile");

int round_up(int x, int to) {
  return (x + to - 1) / to * to;
}

// The most bytes one bound shader storage range may span: the context's
// limit, or PHASECAST_MAX_STORAGE_BLOCK_BYTES when lower (tests split small
// scenes with it; docs/client.md).
std::size_t storage_block_limit(const GlFunctions& gl) {
  GLint limit = 0;
  gl.glGetIntegerv(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &limit);
  auto bytes = static_cast<std::size_t>(static_cast<unsigned>(limit));
  if (const char* cap = std::getenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES")) {
    char* end = nullptr;
    const unsigned long long v = std::strtoull(cap, &end, 10);
    if (end != cap && *end == 0 && v > 0) bytes = std::min<std::size_t>(bytes, v);
  }
  return bytes;
}

}  // namespace

struct LowRankRenderer::Impl {
  RenderBackend& backend;
  GlFunctions gl;
  ClientBasis basis;  // sizes and flags; the bulk data lives on the GPU
  int width, height;
  float radius;
  GlProgram program, static_program, dot_program, eval_program;
  // Per light-dotted copy (one per instance allocated): the lights it was
  // made with. Instances that see the same light read one copy
  // (dotted_copy), so it is dotted once and read from the caches.
  std::vector<std::optional<Lights>> dotted_lights;
  std::vector<std::size_t> dotted_copy;  // per instance drawn
  // Per instance: the rotations its lights were last turned by, and those lights
  // (rotating SH coefficients costs more than a frame's upload; supports are often still).
  struct TurnedLights {
    Eigen::Matrix3f placement, support;
    std::array<float, 96> lights;
  };
  std::vector<std::optional<TurnedLights>> turned_lights;
  std::uint64_t light_dot_passes = 0;
  VertexArray vao, static_vao, evaluated_vao;
  Evaluation evaluation = Evaluation::per_point_pass;  // as asked for; path() is what runs
  std::array<Buffer, kBindingCount> storage;
  Buffer index_buffer, feedback_buffer, static_buffer;
  Framebuffer framebuffer;
  Renderbuffer colour_buffer, depth_buffer;
  Camera camera;
  float exposure = 1;
  ShLight light;
  bool has_static = false;
  bool has_transfer = false;
  int r_u4 = 0, r_a4 = 0;  // ranks in vec4 blocks (shaders/low_rank.vert)
  Backdrop backdrop = Backdrop::none;
  std::optional<GroundPlane> ground;  // made on the first set_backdrop(ground)
  // Where the instances stand (instance frame -> world); one at the origin by default.
  std::vector<Eigen::Matrix4f> placements{Eigen::Matrix4f::Identity()};
  std::size_t allocated_instances = 0;  // instances the per-instance buffers hold
  float view_radius = 0;                // of the group: depth range and ground
  Eigen::Vector2f ground_centre = Eigen::Vector2f::Zero();
  // Point blocks: when a per-point buffer is larger than one shader storage
  // block may span (block_limit), the passes bind block_points points of
  // every per-point buffer at a time and run one instance at a time.
  std::size_t block_limit = 0;
  int block_points = 0;
  int stride_points = 0;  // S rounded up to kBlockAlign: an instance's share of the dotted buffers
  bool split = false;
  bool half = false;  // U_u and U_a as 16-bit floats (--half)
  BasisLayout layout = BasisLayout::point_tiles;
  // The compute passes' reads (ComputeReads): buffer textures over the
  // storage buffers, on the texture units numbered as their bindings, made
  // when the storage is; the texel programs are linked the first time they run.
  ComputeReads reads = ComputeReads::storage_buffers;
  std::array<Texture, kBindingCount> texel_views;
  std::array<std::size_t, kBindingCount> storage_bytes{};
  bool texels_fit = false;  // every view within GL_MAX_TEXTURE_BUFFER_SIZE
  GlProgram texel_eval_program, texel_dot_program;

  Impl(RenderBackend& b, const ClientBasis& bases, int w, int h, BasisPrecision precision,
       std::optional<BasisLayout> basis_layout)
      : backend(b),
        gl(detail::load_gl_functions(b)),
        basis(bases),
        width(w),
        height(h),
        half(precision == BasisPrecision::float16),
        layout(basis_layout.value_or(llvmpipe() ? BasisLayout::point_rows : BasisLayout::point_tiles)) {
    basis.validate("renderer");
    if (llvmpipe()) keep_freed_heap();
    r_u4 = (basis.rank_u + 3) / 4;  // the programs are compiled with them (with_defines)
    r_a4 = (basis.rank_a + 3) / 4;
    has_transfer = basis.has_transfer();
    radius = scene_radius(basis);
    view_radius = radius;
    camera = scene_camera(basis);
    light = light_probe("grace");
    program = detail::link_vertex_program(gl, with_defines(shaders::low_rank_vert), "low_rank.vert", true);
    static_program = detail::link_vertex_program(gl, shaders::static_mesh_vert, "static_mesh.vert", false);
    dot_program = detail::link_compute_program(gl, with_defines(shaders::light_dot_comp), "light_dot.comp");
    eval_program = detail::link_compute_program(gl, with_defines(shaders::low_rank_comp), "low_rank.comp");
    evaluation = default_evaluation();
    reads = llvmpipe() ? ComputeReads::buffer_textures : ComputeReads::storage_buffers;
    upload_bases();
    create_framebuffer();
    check("setting up the renderer");
  }

  // Point blocks evaluate once per point with transform feedback by range: a
  // triangle may join points of two blocks.
  Evaluation path() const {
    if (!split) return evaluation;
    const std::size_t output = 24 * allocated_instances * static_cast<std::size_t>(basis.points);
    return evaluation == Evaluation::compute_pass && output <= block_limit ? Evaluation::compute_pass
                                                                           : Evaluation::per_point_pass;
  }

  // A shader reading the bases, with PHASECAST_HALF_BASES (--half), the tile
  // size, the ranks and whether there is transfer defined after its #version
  // line: all are fixed per renderer, so no branch runs per basis value and
  // the loops over the ranks unroll.
  std::string with_defines(std::string_view source, std::string_view more = {}) const {
    std::string out(source);
    const std::string defines = fmt::format(
        "{}#define PHASECAST_POINT_TILE {}u\n#define PHASECAST_R_U4 {}\n#define PHASECAST_R_A4 {}\n"
        "#define PHASECAST_HAS_TRANSFER {}\n{}",
        half ? "#define PHASECAST_HALF_BASES\n" : "", point_tile(), r_u4, r_a4, has_transfer, more);
    out.insert(out.find('\n') + 1, defines);
    return out;
  }

  std::size_t point_tile() const { return layout == BasisLayout::point_tiles ? PHASECAST_POINT_TILE : 1; }

  bool llvmpipe() const {
    const auto* renderer = reinterpret_cast<const char*>(gl.glGetString(GL_RENDERER));
    return renderer && std::string_view(renderer).find("llvmpipe") != std::string_view::npos;
  }

  // The fastest measured path for the backend (docs/performance-client.md).
  Evaluation default_evaluation() const {
    return llvmpipe() ? Evaluation::compute_pass : Evaluation::in_draw;
  }

  void set_backdrop(Backdrop b) {
    if (b == Backdrop::ground && !ground) {
      ground.emplace(gl, basis, radius);
      ground->cover(ground_centre, view_radius);
      check("setting up the backdrop");
    }
    backdrop = b;
  }

  void check(const char* what) const {
    const GLenum error = gl.glGetError();
    if (error != GL_NO_ERROR) {
      throw RenderError(
          fmt::format("{} backend: OpenGL error 0x{:04x} while {}", backend.name(), error, what));
    }
  }

  // Empty parts (no U_a) still get a small buffer so every binding is valid.
  // Per-point buffers may be larger than one storage block (point blocks);
  // the per-instance ones (q, instances) are bound whole.
  template <class T>
  void upload_storage(Binding binding, const std::vector<T>& data, const char* part) {
    const bool whole = binding == kReduced || binding == kInstances;
    if (whole && static_cast<std::size_t>(byte_size(data)) > block_limit) {
      throw RenderError(
          fmt::format("{} backend: {} needs {} bytes, more than one shader storage block may hold "
                      "({} bytes): fewer instances",
                      backend.name(), part, byte_size(data), block_limit));
    }
    gl.glBindBuffer(GL_SHADER_STORAGE_BUFFER, storage[binding].get());
    const std::array<T, 4> padding{};
    const auto bytes = data.empty() ? byte_size(std::vector<T>(4)) : byte_size(data);
    gl.glBufferData(GL_SHADER_STORAGE_BUFFER, bytes, data.empty() ? padding.data() : data.data(),
                    GL_STATIC_DRAW);
    storage_bytes[binding] = static_cast<std::size_t>(bytes);
    gl.glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, storage[binding].get());
  }

  void upload_bases() {
    upload_storage_buffers();
    // The client keeps only sizes and flags on the CPU once the GPU has the bases.
    basis.U_u = {};
    basis.U_a = {};
    basis.mean_transfer = {};
    create_index_buffer();
    create_feedback_buffer();
  }

  void upload_storage_buffers() {
    for (auto& buffer : storage) buffer = Buffer(gl);
    block_limit = storage_block_limit(gl);
    stride_points = round_up(basis.points, kBlockAlign);
    upload_storage(kMeanShape, basis.mean_shape, "mean_shape");
    // One tiled copy at a time: the bases are the bulk of the client's memory.
    const auto upload_basis = [&](Binding binding, const std::vector<float>& U, int rank, const char* part) {
      auto tiled = tile_points(pad_columns(U, rank), basis.points, stride_points, point_tile());
      if (half)
        upload_storage(binding, to_half(tiled), part);
      else
        upload_storage(binding, tiled, part);
    };
    upload_basis(kDisplacementBasis, basis.U_u, basis.rank_u, "U_u");
    upload_basis(kTransferBasis, basis.U_a, basis.rank_a, "U_a");
    upload_storage(kMeanTransfer, tile_points(basis.mean_transfer, basis.points, stride_points, point_tile()),
                   "mean_transfer");
    upload_storage(kPointFlags, point_flags(basis), "flags");
    upload_storage(kRestNormals, basis.normals, "normals");
    allocate_instances(placements.size());
  }

  // The buffers that hold something per instance: q, placement, support and
  // lights, and what light_dot.comp writes (M_bar.L, a vec4 per point; U_a.L,
  // 3 r_a4 vec4s per point, tiled), and the per-point pass's output.
  void allocate_instances(std::size_t n) {
    const auto points = static_cast<std::size_t>(stride_points);
    plan_point_blocks(n);
    upload_storage(kReduced, std::vector<float>(n * static_cast<std::size_t>(4 * (r_u4 + r_a4)) + 4), "q");
    upload_storage(kMeanDotted, std::vector<float>(n * 4 * points), "M_bar.L");
    upload_storage(kBasisDotted, std::vector<float>(n * 12 * points * static_cast<std::size_t>(r_a4)),
                   "U_a.L");
    upload_storage(kInstances, std::vector<float>(n * kInstanceFloats), "instances");
    dotted_lights.assign(n, std::nullopt);
    turned_lights.assign(n, std::nullopt);
    allocated_instances = n;
    if (feedback_buffer) create_feedback_buffer();
    attach_texel_views();
  }

  // The format a binding is read in as a buffer texture (low_rank_eval.glsl,
  // light_dot.comp: PHASECAST_TEXEL_READS), and its texel's bytes; 0 for
  // what the compute passes do not read.
  std::pair<GLenum, std::size_t> texel_format(Binding b) const {
    switch (b) {
      case kMeanShape:
      case kRestNormals:
        return {GL_RGB32F, 12};
      case kDisplacementBasis:
      case kTransferBasis:
        return half ? std::pair<GLenum, std::size_t>{GL_RG32UI, 8}
                    : std::pair<GLenum, std::size_t>{GL_RGBA32F, 16};
      case kPointFlags:
        return {GL_R32UI, 4};
      case kMeanTransfer:
      case kReduced:
      case kMeanDotted:
      case kBasisDotted:
      case kInstances:
        return {GL_RGBA32F, 16};
      default:
        return {0, 0};
    }
  }

  // (Re)attaches every buffer texture to its storage buffer, whose data store
  // the uploads above may have made anew.
  void attach_texel_views() {
    GLint limit = 0;
    gl.glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &limit);
    texels_fit = true;
    for (GLuint b = 0; b < kBindingCount; ++b) {
      const auto [format, texel] = texel_format(static_cast<Binding>(b));
      if (format == 0) continue;
      texels_fit = texels_fit && storage_bytes[b] / texel <= static_cast<std::size_t>(limit);
      if (!texel_views[b]) texel_views[b] = Texture(gl);
      gl.glBindTexture(GL_TEXTURE_BUFFER, texel_views[b].get());
      gl.glTexBuffer(GL_TEXTURE_BUFFER, format, storage[b].get());
    }
    gl.glBindTexture(GL_TEXTURE_BUFFER, 0);
  }

  bool texel_reads() const { return reads == ComputeReads::buffer_textures && !split && texels_fit; }

  // The compute passes' programs for their reads.
  const GlProgram& compute_program() {
    if (!texel_reads()) return eval_program;
    if (!texel_eval_program) texel_eval_program = link_texel_program(shaders::low_rank_comp, "low_rank.comp");
    return texel_eval_program;
  }
  const GlProgram& light_dot_program() {
    if (!texel_reads()) return dot_program;
    if (!texel_dot_program) texel_dot_program = link_texel_program(shaders::light_dot_comp, "light_dot.comp");
    return texel_dot_program;
  }
  GlProgram link_texel_program(std::string_view source, const char* name) const {
    return detail::link_compute_program(gl, with_defines(source, "#define PHASECAST_TEXEL_READS\n"), name);
  }

  // Texture units, like buffer bindings, belong to the context.
  void bind_texel_views() {
    for (GLuint b = 0; b < kBindingCount; ++b) {
      if (!texel_views[b]) continue;
      gl.glActiveTexture(GL_TEXTURE0 + b);
      gl.glBindTexture(GL_TEXTURE_BUFFER, texel_views[b].get());
    }
    gl.glActiveTexture(GL_TEXTURE0);
  }

  // The triangles, recorded in vao: the in_draw evaluation draws with it.
  void create_index_buffer() {
    vao = VertexArray(gl);
    gl.glBindVertexArray(vao.get());
    index_buffer = Buffer(gl);
    gl.glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, index_buffer.get());
    gl.glBufferData(GL_ELEMENT_ARRAY_BUFFER, byte_size(basis.triangles), basis.triangles.data(),
                    GL_STATIC_DRAW);
    gl.glBindVertexArray(0);
  }

  // Where the per-point pass writes, and evaluated_vao to draw triangles from it.
  void create_feedback_buffer() {
    feedback_buffer = Buffer(gl);
    gl.glBindBuffer(GL_TRANSFORM_FEEDBACK_BUFFER, feedback_buffer.get());
    gl.glBufferData(GL_TRANSFORM_FEEDBACK_BUFFER,
                    static_cast<GLsizeiptr>(6 * sizeof(float) * allocated_instances) * basis.points, nullptr,
                    GL_DYNAMIC_COPY);
    evaluated_vao = VertexArray(gl);
    describe_vertices(evaluated_vao, feedback_buffer);
  }

  // Interleaved position, radiance (6 floats per point) as attributes 0, 1
  // of static_mesh.vert, indexed by the triangles.
  void describe_vertices(const VertexArray& vertex_array, const Buffer& buffer) {
    gl.glBindVertexArray(vertex_array.get());
    gl.glBindBuffer(GL_ARRAY_BUFFER, buffer.get());
    const auto stride = static_cast<GLsizei>(6 * sizeof(float));
    gl.glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, nullptr);
    gl.glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride,
                             reinterpret_cast<const void*>(3 * sizeof(float)));
    gl.glEnableVertexAttribArray(0);
    gl.glEnableVertexAttribArray(1);
    gl.glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, index_buffer.get());
    gl.glBindVertexArray(0);
  }

  void create_framebuffer() {
    framebuffer = Framebuffer(gl);
    gl.glBindFramebuffer(GL_FRAMEBUFFER, framebuffer.get());
    colour_buffer = attach_renderbuffer(GL_RGBA8, GL_COLOR_ATTACHMENT0);
    depth_buffer = attach_renderbuffer(GL_DEPTH_COMPONENT24, GL_DEPTH_ATTACHMENT);
    if (gl.glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
      throw RenderError(fmt::format("{} backend: a {}x{} RGBA8 + depth framebuffer is incomplete",
                                    backend.name(), width, height));
    }
  }

  // A width x height renderbuffer attached to the bound framebuffer.
  Renderbuffer attach_renderbuffer(GLenum format, GLenum attachment) {
    Renderbuffer renderbuffer(gl);
    gl.glBindRenderbuffer(GL_RENDERBUFFER, renderbuffer.get());
    gl.glRenderbufferStorage(GL_RENDERBUFFER, format, width, height);
    gl.glFramebufferRenderbuffer(GL_FRAMEBUFFER, attachment, GL_RENDERBUFFER, renderbuffer.get());
    return renderbuffer;
  }

  // Buffer bindings belong to the context, which other renderers may share
  // (tests, benchmarks): each draw binds its own.
  void bind_storage() {
    for (GLuint b = 0; b < kBindingCount; ++b)
      gl.glBindBufferBase(GL_SHADER_STORAGE_BUFFER, b, storage[b].get());
  }

  // Bytes per point of each per-point buffer (the dotted ones: per instance).
  std::array<std::size_t, kBindingCount> bytes_per_point() const {
    std::array<std::size_t, kBindingCount> b{};
    b[kMeanShape] = 12;
    const std::size_t scalar = half ? 2 : 4;  // bytes per basis value
    b[kDisplacementBasis] = 12 * scalar * static_cast<std::size_t>(r_u4);
    b[kMeanTransfer] = has_transfer ? 192 : 0;
    b[kTransferBasis] = has_transfer ? 192 * scalar * static_cast<std::size_t>(r_a4) : 0;
    b[kPointFlags] = 4;
    b[kRestNormals] = 12;
    b[kMeanDotted] = 16;
    b[kBasisDotted] = 48 * static_cast<std::size_t>(r_a4);
    return b;
  }

  // One block for everything when every buffer, all instances' dotted
  // values included, fits one storage block; else blocks of as many points
  // as the widest buffer's limit allows.
  void plan_point_blocks(std::size_t instances) {
    const auto bpp = bytes_per_point();
    const std::size_t widest = *std::max_element(bpp.begin(), bpp.end());
    const auto S = static_cast<std::size_t>(stride_points);
    split = false;
    for (int b = 0; b < static_cast<int>(kBindingCount); ++b) {
      const bool dotted = b == kMeanDotted || b == kBasisDotted;
      if (bpp[static_cast<std::size_t>(b)] * S * (dotted ? instances : 1) > block_limit) split = true;
    }
    block_points = stride_points;
    if (!split) return;
    block_points = static_cast<int>(block_limit / widest) / kBlockAlign * kBlockAlign;
    if (block_points < kBlockAlign) {
      throw RenderError(
          fmt::format("{} backend: {} points of {} bytes each exceed one shader storage block ({} bytes)",
                      backend.name(), kBlockAlign, widest, block_limit));
    }
  }

  // Binds points [first, first + count) of every per-point buffer, and of
  // light-dotted copy `copy`; a tiled buffer's range ends on a whole tile.
  void bind_point_block(int first, int count, std::size_t copy) {
    const auto bpp = bytes_per_point();
    for (int b = 0; b < static_cast<int>(kBindingCount); ++b) {
      const auto size = bpp[static_cast<std::size_t>(b)];
      if (size == 0) continue;
      const bool dotted = b == kMeanDotted || b == kBasisDotted;
      const bool tiled =
          b == kBasisDotted || b == kDisplacementBasis || b == kMeanTransfer || b == kTransferBasis;
      const std::size_t point =
          (dotted ? copy * static_cast<std::size_t>(stride_points) : 0) + static_cast<std::size_t>(first);
      const auto points = static_cast<std::size_t>(tiled ? round_up(count, kBlockAlign) : count);
      gl.glBindBufferRange(GL_SHADER_STORAGE_BUFFER, static_cast<GLuint>(b),
                           storage[static_cast<std::size_t>(b)].get(), static_cast<GLintptr>(point * size),
                           static_cast<GLsizeiptr>(points * size));
    }
  }

  void set_uniforms(const GlProgram& p, std::span<const FrameState> frames) {
    bind_storage();
    p.use();
    const Eigen::Matrix4f vp = view_projection(camera, width, height, view_radius);
    gl.glUniformMatrix4fv(p.uniform("view_projection"), 1, GL_FALSE, vp.data());
    gl.glUniform1f(p.uniform("exposure"), exposure);
    if (&p == &program) set_low_rank_uniforms(frames);
  }

  // What only low_rank.vert reads: ranks, and per instance q, support,
  // placement and lights.
  void set_low_rank_uniforms(std::span<const FrameState> frames) {
    set_evaluation_uniforms(program);
    std::vector<float> instances(frames.size() * kInstanceFloats);
    std::vector<const Lights*> lights(frames.size());
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const Eigen::Matrix4f& placement = placements[i];
      const Eigen::Matrix4f support = placement * support_matrix(frames[i]);
      lights[i] = &lights_of(i, placement, support);
      float* out = &instances[i * kInstanceFloats];
      std::copy_n(placement.data(), 16, out);
      std::copy_n(support.data(), 16, out + 16);
      std::copy(lights[i]->begin(), lights[i]->end(), out + 32);
    }
    dotted_copy.assign(frames.size(), 0);
    if (has_transfer) update_light_dotted(lights);
    for (std::size_t i = 0; i < frames.size(); ++i)
      instances[i * kInstanceFloats + kDottedCopyFloat] = static_cast<float>(dotted_copy[i]);
    program.use();  // update_light_dotted may have switched to dot_program
    gl.glBindBuffer(GL_SHADER_STORAGE_BUFFER, storage[kInstances].get());
    gl.glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, byte_size(instances), instances.data());
    upload_reduced(frames);
  }

  // What low_rank_eval.glsl reads, for the vertex or the compute program.
  void set_evaluation_uniforms(const GlProgram& p) {
    p.use();
    gl.glUniform1i(p.uniform("first_point"), 0);
    gl.glUniform1i(p.uniform("instance_base"), 0);
    gl.glUniform1i(p.uniform("dotted_stride"), stride_points);
    gl.glUniform1i(p.uniform("points"), basis.points);
  }

  // Per-frame upload: per instance q_u then q_a, each padded to vec4 blocks.
  void upload_reduced(std::span<const FrameState> frames) {
    const auto stride = static_cast<std::size_t>(4 * (r_u4 + r_a4));
    std::vector<float> q(frames.size() * stride, 0.0f);
    for (std::size_t i = 0; i < frames.size(); ++i) {
      std::copy(frames[i].q_u.begin(), frames[i].q_u.end(),
                q.begin() + static_cast<std::ptrdiff_t>(i * stride));
      std::copy(frames[i].q_a.begin(), frames[i].q_a.end(),
                q.begin() + static_cast<std::ptrdiff_t>(i * stride) + 4 * r_u4);
    }
    gl.glBindBuffer(GL_SHADER_STORAGE_BUFFER, storage[kReduced].get());
    if (!q.empty()) gl.glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, byte_size(q), q.data());
  }

  // instance_lights, again only when the instance's rotations changed.
  const Lights& lights_of(std::size_t i, const Eigen::Matrix4f& placement, const Eigen::Matrix4f& support) {
    auto& seen = turned_lights[i];
    const Eigen::Matrix3f p = placement.topLeftCorner<3, 3>(), r = support.topLeftCorner<3, 3>();
    if (!seen || seen->placement != p || seen->support != r)
      seen = {p, r, instance_lights(placement, support)};
    return seen->lights;
  }

  // The world light as an instance's points see it (§5.3): rotated into the
  // instance's frame for free points and into its support frame for
  // attached ones. An unrotated placement leaves the world light as it is.
  Lights instance_lights(const Eigen::Matrix4f& placement, const Eigen::Matrix4f& support) const {
    Lights lights{};
    const Eigen::Matrix3d turn = placement.topLeftCorner<3, 3>().cast<double>();
    const auto world = turn.isIdentity(0) ? light.packed() : light_in_support_frame(light, turn).packed();
    const auto local = light_in_support_frame(light, support.topLeftCorner<3, 3>().cast<double>()).packed();
    std::copy(world.begin(), world.end(), lights.begin());
    std::copy(local.begin(), local.end(), lights.begin() + 48);
    return lights;
  }

  // Points each instance at a light-dotted copy made with the light it sees:
  // one that holds it already, else a copy no instance needs this frame,
  // dotted anew (a new light or a rotated support). Instances that see the
  // same light share a copy.
  void update_light_dotted(const std::vector<const Lights*>& lights) {
    std::map<Lights, std::size_t> held;
    for (std::size_t c = 0; c < dotted_lights.size(); ++c)
      if (dotted_lights[c]) held.emplace(*dotted_lights[c], c);
    std::vector<bool> needed(dotted_lights.size(), false);
    std::vector<std::size_t> missing;
    for (std::size_t i = 0; i < lights.size(); ++i) {
      const auto it = held.find(*lights[i]);
      if (it == held.end()) {
        missing.push_back(i);
      } else {
        dotted_copy[i] = it->second;
        needed[it->second] = true;
      }
    }
    std::map<Lights, std::size_t> made;
    std::size_t spare = 0;
    for (const std::size_t i : missing) {
      auto [it, fresh] = made.emplace(*lights[i], 0);
      if (fresh) {
        while (needed[spare]) ++spare;  // copies >= instances >= lights in use
        needed[spare] = true;
        it->second = spare;
        dot_light_into(spare, *lights[i]);
      }
      dotted_copy[i] = it->second;
    }
  }

  // Dots the transfer bases with `lights` into light-dotted copy `copy`.
  void dot_light_into(std::size_t copy, const Lights& lights) {
    const GlProgram& dot = light_dot_program();
    dot.use();
    if (texel_reads()) bind_texel_views();
    gl.glUniform4fv(dot.uniform("light"), 24, lights.data());
    auto dispatch = [&](int count, int out_base) {
      gl.glUniform1i(dot.uniform("points"), count);
      gl.glUniform1i(dot.uniform("out_base"), out_base);
      gl.glDispatchCompute(static_cast<GLuint>((count + 63) / 64), 1, 1);
    };
    if (!split) {
      dispatch(basis.points, static_cast<int>(copy) * stride_points);
    } else {
      for (int first = 0; first < basis.points; first += block_points) {
        const int count = std::min(block_points, basis.points - first);
        bind_point_block(first, count, copy);
        dispatch(count, 0);
      }
      bind_storage();
    }
    gl.glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
    dotted_lights[copy] = lights;
    ++light_dot_passes;
  }

  void begin_frame() {
    gl.glBindFramebuffer(GL_FRAMEBUFFER, framebuffer.get());
    gl.glViewport(0, 0, width, height);
    const auto& clear = backdrop == Backdrop::ground ? kBackdropBackground : kPlainBackground;
    gl.glClearColor(clear[0], clear[1], clear[2], 1.0f);
    gl.glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    if (backdrop == Backdrop::ground) ground->draw(camera, width, height, light, exposure);
    gl.glEnable(GL_DEPTH_TEST);
    gl.glDepthFunc(GL_LESS);
    // Thin surfaces (cloth, leaves) are two coincident layers of scene points
    // with opposite windings, each with its own transfer (§4.1): only the side
    // facing the camera may be drawn (package triangles are counter-clockwise
    // seen from their normal's side, docs/package-format.md).
    gl.glEnable(GL_CULL_FACE);
  }

  void show() {
    if (!backend.shows_frames()) return;
    gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer.get());
    gl.glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    gl.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    backend.present();
  }

  // Pass 1: the low-rank program once per scene point and instance
  // (GL_POINTS, rasterizer off), positions and radiance captured into
  // feedback_buffer, instance after instance.
  void evaluation_pass(std::span<const FrameState> frames) {
    set_uniforms(program, frames);
    gl.glEnable(GL_RASTERIZER_DISCARD);
    gl.glBindVertexArray(vao.get());
    if (!split) {
      gl.glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, feedback_buffer.get());
      gl.glBeginTransformFeedback(GL_POINTS);
      gl.glDrawArraysInstanced(GL_POINTS, 0, basis.points, static_cast<GLsizei>(frames.size()));
      gl.glEndTransformFeedback();
    } else {
      evaluate_point_blocks(frames.size());
    }
    gl.glBindVertexArray(0);
    gl.glDisable(GL_RASTERIZER_DISCARD);
  }

  // The per-point pass as a compute shader, writing where transform feedback
  // would (feedback_buffer), for the triangle draw's vertex attributes.
  void compute_pass(std::span<const FrameState> frames) {
    set_uniforms(program, frames);  // lights, dotted transfer, q and the instances' data
    const GlProgram& eval = compute_program();
    set_evaluation_uniforms(eval);
    if (texel_reads()) bind_texel_views();
    gl.glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kEvaluated, feedback_buffer.get());
    auto dispatch = [&](int count, int out_base, int out_stride, std::size_t instances) {
      gl.glUniform1i(eval.uniform("points"), count);
      gl.glUniform1i(eval.uniform("out_base"), out_base);
      gl.glUniform1i(eval.uniform("out_stride"), out_stride);
      gl.glDispatchCompute(static_cast<GLuint>((count + 63) / 64), static_cast<GLuint>(instances), 1);
    };
    if (!split) {
      dispatch(basis.points, 0, basis.points, frames.size());
    } else {
      gl.glUniform1i(eval.uniform("dotted_stride"), 0);
      for (std::size_t i = 0; i < frames.size(); ++i) {
        gl.glUniform1i(eval.uniform("instance_base"), static_cast<GLint>(i));
        for (int first = 0; first < basis.points; first += block_points) {
          const int count = std::min(block_points, basis.points - first);
          bind_point_block(first, count, dotted_copy[i]);
          dispatch(count, static_cast<int>(i) * basis.points + first, 0, 1);
        }
      }
      bind_storage();
    }
    gl.glMemoryBarrier(GL_VERTEX_ATTRIB_ARRAY_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  }

  // The evaluated points of every instance, by the drawing path's own pass.
  void run_evaluation(std::span<const FrameState> frames) {
    if (path() == Evaluation::compute_pass) {
      compute_pass(frames);
    } else {
      evaluation_pass(frames);
    }
  }

  // Point blocks: each block of each instance captured where the instanced
  // draw would have put it (instance i's points start at i S).
  void evaluate_point_blocks(std::size_t instances) {
    gl.glUniform1i(program.uniform("dotted_stride"), 0);
    for (std::size_t i = 0; i < instances; ++i) {
      gl.glUniform1i(program.uniform("instance_base"), static_cast<GLint>(i));
      for (int first = 0; first < basis.points; first += block_points) {
        const int count = std::min(block_points, basis.points - first);
        bind_point_block(first, count, dotted_copy[i]);
        gl.glUniform1i(program.uniform("first_point"), first);
        const auto at = (i * static_cast<std::size_t>(basis.points) + static_cast<std::size_t>(first)) * 6 *
                        sizeof(float);
        gl.glBindBufferRange(GL_TRANSFORM_FEEDBACK_BUFFER, 0, feedback_buffer.get(),
                             static_cast<GLintptr>(at),
                             static_cast<GLsizeiptr>(static_cast<std::size_t>(count) * 6 * sizeof(float)));
        gl.glBeginTransformFeedback(GL_POINTS);
        gl.glDrawArrays(GL_POINTS, first, count);
        gl.glEndTransformFeedback();
      }
    }
    bind_storage();
  }

  // The triangles of every instance in one draw: from the per-point pass's
  // output (instance i's points start at i S), or evaluated in the draw.
  void draw_triangles(const GlProgram& p, const VertexArray& vertex_array,
                      std::span<const FrameState> frames) {
    begin_frame();
    set_uniforms(p, frames);
    gl.glBindVertexArray(vertex_array.get());
    const auto count = static_cast<GLsizei>(basis.triangles.size());
    const auto n = static_cast<GLsizei>(frames.size());
    if (&p == &program) {
      gl.glDrawElementsInstanced(GL_TRIANGLES, count, GL_UNSIGNED_INT, nullptr, n);
    } else {
      std::vector<GLsizei> counts(frames.size(), count);
      std::vector<const void*> offsets(frames.size(), nullptr);
      std::vector<GLint> base_vertices(frames.size());
      for (std::size_t i = 0; i < frames.size(); ++i) base_vertices[i] = static_cast<GLint>(i) * basis.points;
      gl.glMultiDrawElementsBaseVertex(GL_TRIANGLES, counts.data(), GL_UNSIGNED_INT, offsets.data(), n,
                                       base_vertices.data());
    }
    gl.glBindVertexArray(0);
  }

  // One frame per placement.
  void check_frames(std::span<const FrameState> frames) const {
    if (frames.size() != placements.size()) {
      throw RenderError(fmt::format("{} frames for {} placed instances (expected one frame per instance)",
                                    frames.size(), placements.size()));
    }
    for (const auto& f : frames) validate_frame(f, basis, "renderer");
  }

  void draw(std::span<const FrameState> frames) {
    check_frames(frames);
    if (path() != Evaluation::in_draw) {
      // Each point is evaluated exactly once; the triangles then read the
      // results as plain vertex attributes (shared vertices are not re-run).
      run_evaluation(frames);
      draw_triangles(static_program, evaluated_vao, frames);
    } else {
      draw_triangles(program, vao, frames);
    }
    show();
    check("drawing a frame");
  }

  Image read_pixels() {
    Image image{width, height, std::vector<std::uint8_t>(static_cast<std::size_t>(4 * width * height))};
    gl.glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer.get());
    gl.glReadBuffer(GL_COLOR_ATTACHMENT0);
    gl.glPixelStorei(GL_PACK_ALIGNMENT, 1);
    std::vector<std::uint8_t> bottom_up(image.rgba.size());
    gl.glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, bottom_up.data());
    check("reading back pixels");
    copy_rows_flipped(bottom_up, image);
    return image;
  }

  VertexDump evaluate(std::span<const FrameState> frames) {
    check_frames(frames);
    run_evaluation(frames);
    const std::size_t points = frames.size() * static_cast<std::size_t>(basis.points);
    std::vector<float> captured(6 * points);
    gl.glBindBuffer(GL_TRANSFORM_FEEDBACK_BUFFER, feedback_buffer.get());
    gl.glGetBufferSubData(GL_TRANSFORM_FEEDBACK_BUFFER, 0, byte_size(captured), captured.data());
    check("capturing vertices by transform feedback");
    return deinterleave(captured, points);
  }

  // Rigid placements only: the light is turned with them (instance_lights),
  // which a scale or shear would make wrong.
  void set_placements(std::vector<Eigen::Matrix4f> next) {
    if (next.empty()) throw RenderError("no placement given (expected at least one instance)");
    for (std::size_t i = 0; i < next.size(); ++i) {
      const Eigen::Matrix3f r = next[i].topLeftCorner<3, 3>();
      if (!next[i].allFinite() || !(r.transpose() * r).isIdentity(1e-4f) || r.determinant() < 0 ||
          !next[i].row(3).isApprox(Eigen::RowVector4f(0, 0, 0, 1))) {
        throw RenderError(
            fmt::format("placement {} is not a rotation and a translation (expected a rigid transform)", i));
      }
    }
    placements = std::move(next);
    if (placements.size() != allocated_instances) {
      allocate_instances(placements.size());
      has_static = false;  // its meshes were as many as the old placements
    }
    frame_group();
  }

  // The group's centre and radius: the depth range and the ground take in
  // every instance.
  void frame_group() {
    Eigen::AlignedBox3f rest;
    for (std::size_t v = 0; v < static_cast<std::size_t>(basis.points); ++v)
      rest.extend(
          Eigen::Vector3f(basis.mean_shape[3 * v], basis.mean_shape[3 * v + 1], basis.mean_shape[3 * v + 2]));
    Eigen::AlignedBox3f group;
    for (const auto& p : placements) group.extend((p * rest.center().homogeneous()).head<3>());
    view_radius = radius + 0.5f * group.diagonal().norm();
    ground_centre = {group.center().x(), group.center().z()};
    if (ground) ground->cover(ground_centre, view_radius);
  }

  // One mesh per placed instance, instance after instance (what evaluate() gives).
  void set_static_mesh(const VertexDump& d) {
    const std::size_t points = placements.size() * static_cast<std::size_t>(basis.points);
    if (d.positions.size() != 3 * points || d.radiance.size() != d.positions.size()) {
      throw RenderError(
          fmt::format("static mesh has {} positions and {} radiance values (expected 3S = {} each per "
                      "instance, {} instances)",
                      d.positions.size(), d.radiance.size(), 3 * basis.points, placements.size()));
    }
    const std::vector<float> interleaved = interleave(d, static_cast<int>(points));
    if (!static_vao) {
      static_vao = VertexArray(gl);
      static_buffer = Buffer(gl);
    }
    gl.glBindBuffer(GL_ARRAY_BUFFER, static_buffer.get());
    gl.glBufferData(GL_ARRAY_BUFFER, byte_size(interleaved), interleaved.data(), GL_STATIC_DRAW);
    describe_vertices(static_vao, static_buffer);
    has_static = true;
    check("uploading the static mesh");
  }

  void draw_static() {
    if (!has_static)
      throw RenderError("draw_static: no static mesh was uploaded (call set_static_mesh first)");
    const std::vector<FrameState> rest(placements.size());
    draw_triangles(static_program, static_vao, rest);
    check("drawing the static mesh");
  }
};

LowRankRenderer::LowRankRenderer(RenderBackend& backend, const ClientBasis& basis, int width, int height,
                                 BasisPrecision precision, std::optional<BasisLayout> layout)
    : impl_(std::make_unique<Impl>(backend, basis, width, height, precision, layout)) {}
LowRankRenderer::~LowRankRenderer() = default;

void LowRankRenderer::set_light(const ShLight& world_light) {
  impl_->light = world_light;
  std::fill(impl_->turned_lights.begin(), impl_->turned_lights.end(), std::nullopt);
}
void LowRankRenderer::set_camera(const Camera& camera) {
  impl_->camera = camera;
}
void LowRankRenderer::set_exposure(float exposure) {
  impl_->exposure = exposure;
}
std::uint64_t LowRankRenderer::light_dot_passes() const {
  return impl_->light_dot_passes;
}
void LowRankRenderer::set_evaluation(Evaluation evaluation) {
  impl_->evaluation = evaluation;
}
Evaluation LowRankRenderer::evaluation() const {
  return impl_->path();
}
BasisLayout LowRankRenderer::basis_layout() const {
  return impl_->layout;
}
void LowRankRenderer::set_compute_reads(ComputeReads reads) {
  impl_->reads = reads;
}
ComputeReads LowRankRenderer::compute_reads() const {
  return impl_->texel_reads() ? ComputeReads::buffer_textures : ComputeReads::storage_buffers;
}
void LowRankRenderer::set_backdrop(Backdrop backdrop) {
  impl_->set_backdrop(backdrop);
}
void LowRankRenderer::draw(const FrameState& frame) {
  impl_->draw(std::span(&frame, 1));
}
Image LowRankRenderer::render(const FrameState& frame) {
  impl_->draw(std::span(&frame, 1));
  return impl_->read_pixels();
}
VertexDump LowRankRenderer::evaluate(const FrameState& frame) {
  return impl_->evaluate(std::span(&frame, 1));
}
void LowRankRenderer::set_placements(std::vector<Eigen::Matrix4f> placements) {
  impl_->set_placements(std::move(placements));
}
std::size_t LowRankRenderer::instances() const {
  return impl_->placements.size();
}
void LowRankRenderer::draw(std::span<const FrameState> frames) {
  impl_->draw(frames);
}
Image LowRankRenderer::render(std::span<const FrameState> frames) {
  impl_->draw(frames);
  return impl_->read_pixels();
}
VertexDump LowRankRenderer::evaluate(std::span<const FrameState> frames) {
  return impl_->evaluate(frames);
}
void LowRankRenderer::set_static_mesh(const VertexDump& vertices) {
  impl_->set_static_mesh(vertices);
}
void LowRankRenderer::draw_static() {
  impl_->draw_static();
}
std::size_t LowRankRenderer::gpu_bytes_per_point() const {
  const auto& i = *impl_;
  const auto bpp = i.bytes_per_point();
  std::size_t bytes = 0;
  for (std::size_t b = 0; b < bpp.size(); ++b) {
    const bool dotted = b == kMeanDotted || b == kBasisDotted;
    bytes += bpp[b] * (dotted ? i.allocated_instances : 1);
  }
  return bytes;
}
int LowRankRenderer::point_blocks() const {
  const auto& i = *impl_;
  return i.split ? (i.basis.points + i.block_points - 1) / i.block_points : 1;
}
void LowRankRenderer::finish() {
  impl_->gl.glFinish();
}
Image LowRankRenderer::read_pixels() {
  return impl_->read_pixels();
}
std::string LowRankRenderer::gl_description() const {
  const auto* version = reinterpret_cast<const char*>(impl_->gl.glGetString(GL_VERSION));
  const auto* renderer = reinterpret_cast<const char*>(impl_->gl.glGetString(GL_RENDERER));
  return fmt::format("OpenGL {}, {}", version ? version : "?", renderer ? renderer : "?");
}

}  // namespace phasecast::client
