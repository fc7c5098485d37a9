#pragma once
// glTF 2.0 export of a scene package and of a recorded session
// (phasecast-export, docs/gltf.md): the render mesh at the mean shape x̄ with
// one morph target per column of U_u, so that a glTF viewer's
// mean + Σ_k weight_k · target_k is exactly eq. 7, x = x̄ + U_u q_u; the
// support as a parent node of the attached points; vertex colours from the
// mean transfer M̄ under a light; and, from a recording, one animation whose
// morph weights are q_u and whose support node follows the support transform.
// Written with tinygltf (Debian's libtinygltf-dev).

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace phasecast::client {

struct GltfExportOptions {
  std::filesystem::path package;                   // scene package (.h5)
  std::filesystem::path out;                       // binary glTF (.glb)
  std::optional<std::filesystem::path> recording;  // session to animate (.phcrec)
  std::optional<std::uint32_t> instance;           // recorded instance (default: the first of the scene)
  std::string
      light;  // light probe the vertex colours are lit by (empty: the scene's [view] light, else grace)
};

struct GltfExportSummary {
  std::string scene;
  int points = 0;             // S
  int triangles = 0;          // triangles written
  int dropped_triangles = 0;  // triangles joining attached and world points: no single node can carry them
  int rank_u = 0;             // morph targets per mesh
  bool has_transfer = false;  // colours from M̄ (else the renderer's grey diffuse fallback)
  std::optional<std::uint32_t> instance;  // the animated instance, with a recording
  std::uint64_t first_frame = 0;          // its first recorded frame: animation time 0
  std::size_t frames = 0;                 // keyframes
  double duration_s = 0;                  // (last - first frame) * dt
  std::size_t animation_bytes = 0;        // keyframe data in the file: times, weights, support
  bool animated = false;                  // an animation was written (not when nothing in the file moves)
  bool recording_truncated = false;       // its last record was cut short (a crash) and dropped
  std::uintmax_t file_bytes = 0;

  // The same session as a vertex cache (Alembic, PC2, MDD): 3S floats per frame.
  std::size_t vertex_cache_bytes_per_frame() const { return 12 * static_cast<std::size_t>(points); }
  double animation_bytes_per_frame() const {
    return frames ? static_cast<double>(animation_bytes) / static_cast<double>(frames) : 0.0;
  }
};

// Reads the package (and the recording), builds the glTF model and writes it
// atomically to options.out. Throws std::exception with a one-line message
// naming the input and what was expected: package not valid, recording of
// another package or scene, instance absent, a rank that does not match, an
// output path that is not .glb or cannot be written.
GltfExportSummary export_gltf(const GltfExportOptions& options);

// What phasecast-export prints: the file, its content and the bytes per frame.
std::string describe(const GltfExportSummary& summary, const std::filesystem::path& out);

}  // namespace phasecast::client
