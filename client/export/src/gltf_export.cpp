#include "phasecast/client/gltf_export.h"

#include "phasecast/client/camera.h"
#include "phasecast/client/client_basis.h"
#include "phasecast/client/frame_sources.h"
#include "phasecast/client/frame_state.h"
#include "phasecast/client/sh_light.h"
#include "phasecast/core/hash.h"
#include "phasecast/core/package.h"
#include "phasecast/core/recording.h"
#include "phasecast/core/sh.h"

#include <fmt/format.h>
#include <tiny_gltf.h>
#include <Eigen/Geometry>

#include <unistd.h>
#include <algorithm>
#include <array>
#include <cctype>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <vector>

namespace phasecast::client {
namespace {

namespace fs = std::filesystem;

// ---- the recorded session --------------------------------------------------------

struct Session {
  std::uint32_t instance = 0;
  std::vector<FrameState> frames;  // in stream order, frame numbers increasing
  bool truncated = false;          // the recording's last record was cut short and dropped
};

// The recording must name this package's scene with this package file's
// content hash, as for phasecast-render --replay; the instance is the one
// asked for, or the first of the scene.
Session read_session(const GltfExportOptions& o, const ClientBasis& basis) {
  const std::string rec_name = o.recording->string();
  const core::Recording rec = core::read_recording_file(*o.recording);
  expect_recorded_with(rec, basis, rec_name, o.package.string());
  RecordedFrames recorded = recorded_frames(rec, o.instance, rec_name, basis.scene);
  Session s;
  s.truncated = rec.truncated;
  s.instance = recorded.instance;
  s.frames = std::move(recorded.frames);
  for (std::size_t i = 0; i < s.frames.size(); ++i) {
    // r_u values of q_u, 12 of support, all finite: "recording X: frame 3: ..."
    validate_frame(s.frames[i], basis, "recording " + rec_name);
    if (i > 0 && s.frames[i].frame <= s.frames[i - 1].frame) {
      throw RecordingError(
          fmt::format("recording {}: instance {}: frame {} follows frame {} (expected "
                      "increasing frame numbers)",
                      rec_name, s.instance, s.frames[i].frame, s.frames[i - 1].frame));
    }
  }
  return s;
}

// ---- geometry ---------------------------------------------------------------------

// The points of one glTF mesh: every point with the same `attached` flag, in
// scene point order (vertex i of the attached mesh is the i-th attached point,
// docs/gltf.md), and the triangles among them.
struct Part {
  std::vector<std::uint32_t> points;     // scene point of each vertex
  std::vector<std::uint32_t> triangles;  // vertex indices, 3 per triangle
  bool deformable = false;               // some point moves with U_u: the mesh gets morph targets
};

struct Parts {
  Part world;     // attached = 0: fixed in the world, a root node
  Part attached;  // attached = 1: a child of the support node
  int dropped = 0;
};

// The renderer maps attached points through the support transform and leaves
// the others where they are (low_rank.vert); a glTF node moves its whole mesh,
// so the points go to two meshes. A triangle joining the two kinds would need
// skinning; the scenes have none, and it is left out and counted.
Parts split_by_attachment(const ClientBasis& b) {
  Parts parts;
  std::vector<std::uint32_t> vertex_of(static_cast<std::size_t>(b.points));
  for (std::size_t p = 0; p < vertex_of.size(); ++p) {
    Part& part = b.attached[p] ? parts.attached : parts.world;
    vertex_of[p] = static_cast<std::uint32_t>(part.points.size());
    part.points.push_back(static_cast<std::uint32_t>(p));
    part.deformable = part.deformable || b.deformable[p] != 0;
  }
  for (std::size_t t = 0; t + 2 < b.triangles.size(); t += 3) {
    const auto* corner = &b.triangles[t];
    const bool attached = b.attached[corner[0]] != 0;
    if (b.attached[corner[1]] != attached || b.attached[corner[2]] != attached) {
      ++parts.dropped;
      continue;
    }
    Part& part = attached ? parts.attached : parts.world;
    for (int c = 0; c < 3; ++c) part.triangles.push_back(vertex_of[corner[c]]);
  }
  return parts;
}

Eigen::Vector3f point_of(const std::vector<float>& xyz, std::size_t p) {
  return {xyz[3 * p], xyz[3 * p + 1], xyz[3 * p + 2]};
}

// Unit normals of the exported geometry, x̄: area-weighted face normals (the
// package's rest normals belong to the rest shape); the rest normal where a
// point has no triangle.
std::vector<float> mean_shape_normals(const ClientBasis& b) {
  std::vector<Eigen::Vector3f> sum(static_cast<std::size_t>(b.points), Eigen::Vector3f::Zero());
  for (std::size_t t = 0; t + 2 < b.triangles.size(); t += 3) {
    const auto* v = &b.triangles[t];
    const Eigen::Vector3f a = point_of(b.mean_shape, v[0]);
    const Eigen::Vector3f n = (point_of(b.mean_shape, v[1]) - a).cross(point_of(b.mean_shape, v[2]) - a);
    for (int c = 0; c < 3; ++c) sum[v[c]] += n;
  }
  std::vector<float> normals(3 * sum.size());
  for (std::size_t p = 0; p < sum.size(); ++p) {
    Eigen::Vector3f n = sum[p].norm() > 0 ? sum[p] : point_of(b.normals, p);
    n = n.norm() > 0 ? n.normalized() : Eigen::Vector3f::UnitZ();
    for (int c = 0; c < 3; ++c) normals[3 * p + c] = n[c];
  }
  return normals;
}

// The renderer's colour without an appearance model (low_rank.vert,
// fallback_radiance): grey diffuse, albedo 0.7, of the rest normal, bands 0..2.
std::array<double, 3> fallback_radiance(const Eigen::Vector3f& rest_normal, const ShLight& light) {
  const Eigen::Vector3d n = rest_normal.cast<double>().normalized();
  const auto y = core::sh_basis(n.x(), n.y(), n.z());
  std::array<double, 3> rgb{};
  for (std::size_t c = 0; c < 3; ++c) {
    for (int k = 0; k < 9; ++k) {
      const auto i = static_cast<std::size_t>(k);
      rgb[c] += core::clamped_cosine_band(core::sh_band(k)) * y[i] * light.coefficients[c][i];
    }
    rgb[c] *= 0.7 / std::numbers::pi;
  }
  return rgb;
}

// COLOR_0: the exit radiance M̄·L per channel (§4.2 at q_a = 0), clamped to
// [0, 1] as radiance.frag clamps it; linear, as glTF vertex colours are. The
// light is the world light: attached points see it so at the rest support.
std::vector<float> vertex_colours(const ClientBasis& b, const ShLight& light) {
  std::vector<float> colours(3 * static_cast<std::size_t>(b.points));
  for (std::size_t p = 0; p < static_cast<std::size_t>(b.points); ++p) {
    const auto rgb =
        b.has_transfer()
            ? shade(&b.mean_transfer[static_cast<std::size_t>(core::kTransferPerPoint) * p], light)
            : fallback_radiance(point_of(b.normals, p), light);
    for (std::size_t c = 0; c < 3; ++c) colours[3 * p + c] = static_cast<float>(std::clamp(rgb[c], 0.0, 1.0));
  }
  return colours;
}

// Rows of a 3-per-point array for the points of a part.
std::vector<float> gather3(const std::vector<float>& xyz, const std::vector<std::uint32_t>& points) {
  std::vector<float> out;
  out.reserve(3 * points.size());
  for (const auto p : points) out.insert(out.end(), &xyz[3 * p], &xyz[3 * p] + 3);
  return out;
}

// POSITION deltas of morph target k: column k of U_u at the part's points
// (rows of static points are 0, so only deformable points move).
std::vector<float> target_deltas(const ClientBasis& b, const Part& part, int k) {
  const auto r = static_cast<std::size_t>(b.rank_u);
  std::vector<float> out;
  out.reserve(3 * part.points.size());
  for (const auto p : part.points) {
    for (std::size_t c = 0; c < 3; ++c) out.push_back(b.U_u[(3 * p + c) * r + static_cast<std::size_t>(k)]);
  }
  return out;
}

// ---- the glTF model ----------------------------------------------------------------

// Appends typed arrays to the one binary buffer (the GLB's BIN chunk) and
// describes them by buffer views and accessors.
class GltfBuilder {
 public:
  GltfBuilder() {
    model_.buffers.emplace_back();
    model_.asset.version = "2.0";
    model_.asset.generator = "phasecast-export (tinygltf)";
  }

  // A float accessor of `type` (SCALAR, VEC3, VEC4). Every one gets its
  // per-component min and max: POSITION (targets included) and animation
  // inputs require them, and the rest cost a few bytes.
  int add_floats(const std::vector<float>& values, int type, int target = 0) {
    const int n = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(type));
    tinygltf::Accessor a;
    a.bufferView = add_view(values.data(), values.size() * sizeof(float), target);
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.type = type;
    a.count = values.size() / static_cast<std::size_t>(n);
    a.minValues.assign(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
    a.maxValues.assign(static_cast<std::size_t>(n), -std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < values.size(); ++i) {
      const auto c = i % static_cast<std::size_t>(n);
      a.minValues[c] = std::min(a.minValues[c], double(values[i]));
      a.maxValues[c] = std::max(a.maxValues[c], double(values[i]));
    }
    return push(std::move(a));
  }

  int add_indices(const std::vector<std::uint32_t>& indices) {
    tinygltf::Accessor a;
    a.bufferView = add_view(indices.data(), indices.size() * sizeof(std::uint32_t),
                            TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    a.type = TINYGLTF_TYPE_SCALAR;
    a.count = indices.size();
    return push(std::move(a));
  }

  std::size_t bytes_of(int accessor) const {
    return model_
        .bufferViews[static_cast<std::size_t>(
            model_.accessors[static_cast<std::size_t>(accessor)].bufferView)]
        .byteLength;
  }

  int add_node(tinygltf::Node node) {
    model_.nodes.push_back(std::move(node));
    return static_cast<int>(model_.nodes.size()) - 1;
  }

  tinygltf::Model& model() { return model_; }

 private:
  int add_view(const void* data, std::size_t bytes, int target) {
    auto& buffer = model_.buffers.front().data;
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = buffer.size();  // every view starts 4-byte aligned: all components are 4 bytes
    v.byteLength = bytes;
    v.target = target;
    const auto* begin = static_cast<const unsigned char*>(data);
    buffer.insert(buffer.end(), begin, begin + bytes);
    model_.bufferViews.push_back(v);
    return static_cast<int>(model_.bufferViews.size()) - 1;
  }

  int push(tinygltf::Accessor a) {
    model_.accessors.push_back(std::move(a));
    return static_cast<int>(model_.accessors.size()) - 1;
  }

  tinygltf::Model model_;
};

// The colours are already lit radiance: an unlit material shows them as
// phasecast-render does, instead of lighting them a second time.
int add_unlit_material(tinygltf::Model& m) {
  tinygltf::Material material;
  material.name = "mean transfer under the light (M̄·L)";
  material.doubleSided = true;
  material.pbrMetallicRoughness.metallicFactor = 0;
  material.pbrMetallicRoughness.roughnessFactor = 1;
  material.extensions["KHR_materials_unlit"] = tinygltf::Value(tinygltf::Value::Object());
  m.extensionsUsed.push_back("KHR_materials_unlit");
  m.materials.push_back(std::move(material));
  return static_cast<int>(m.materials.size()) - 1;
}

struct VertexData {
  std::vector<float> normals;  // 3S
  std::vector<float> colours;  // 3S
  int material = -1;
};

// One mesh: x̄ at the part's points, normals, colours, triangles, and with
// deformable points one morph target per column of U_u named after its weight.
int add_mesh(GltfBuilder& g, const ClientBasis& b, const Part& part, const VertexData& data,
             const std::string& name) {
  tinygltf::Primitive prim;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  prim.material = data.material;
  prim.indices = g.add_indices(part.triangles);
  const int array = TINYGLTF_TARGET_ARRAY_BUFFER;
  prim.attributes["POSITION"] = g.add_floats(gather3(b.mean_shape, part.points), TINYGLTF_TYPE_VEC3, array);
  prim.attributes["NORMAL"] = g.add_floats(gather3(data.normals, part.points), TINYGLTF_TYPE_VEC3, array);
  prim.attributes["COLOR_0"] = g.add_floats(gather3(data.colours, part.points), TINYGLTF_TYPE_VEC3, array);
  tinygltf::Mesh mesh;
  mesh.name = name;
  tinygltf::Value::Array target_names;
  for (int k = 0; part.deformable && k < b.rank_u; ++k) {
    prim.targets.push_back(
        {{"POSITION", g.add_floats(target_deltas(b, part, k), TINYGLTF_TYPE_VEC3, array)}});
    target_names.emplace_back(fmt::format("q_u[{}]", k));
    mesh.weights.push_back(0);  // at rest the file shows x̄
  }
  // targetNames: the convention Blender, three.js and Babylon.js read.
  if (!target_names.empty())
    mesh.extras = tinygltf::Value(tinygltf::Value::Object{{"targetNames", tinygltf::Value(target_names)}});
  mesh.primitives.push_back(std::move(prim));
  g.model().meshes.push_back(std::move(mesh));
  return static_cast<int>(g.model().meshes.size()) - 1;
}

// A glTF camera looks down its local -z with +y up: the node's rotation has
// columns (right, up, back) of the scene camera. -1 when eye, target and up
// do not make a frame.
int add_camera_node(GltfBuilder& g, const ClientBasis& b) {
  const Camera c = scene_camera(b);
  const Eigen::Vector3d eye = c.eye.cast<double>(), back = (eye - c.target.cast<double>());
  const Eigen::Vector3d right = c.up.cast<double>().cross(back);
  if (back.norm() == 0 || right.norm() == 0) return -1;
  Eigen::Matrix3d R;
  R.col(2) = back.normalized();
  R.col(0) = right.normalized();
  R.col(1) = R.col(2).cross(R.col(0));
  const Eigen::Quaterniond q(R);
  tinygltf::Camera camera;
  camera.type = "perspective";
  camera.name = "scene camera";
  camera.perspective.yfov = c.fov_y_deg * std::numbers::pi / 180;
  const double radius = scene_radius(b);
  camera.perspective.znear = std::max(1e-3 * radius, 1e-4);
  camera.perspective.zfar = back.norm() + 100 * radius;
  g.model().cameras.push_back(camera);
  tinygltf::Node node;
  node.name = "scene camera";
  node.camera = static_cast<int>(g.model().cameras.size()) - 1;
  node.translation = {eye.x(), eye.y(), eye.z()};
  node.rotation = {q.x(), q.y(), q.z(), q.w()};
  return g.add_node(std::move(node));
}

// ---- the session as an animation ----------------------------------------------------

struct RigidMotion {
  Eigen::Vector3d translation;
  Eigen::Quaterniond rotation;
};

// The support transform x -> R x + t (3x4 row-major) as a node's TRS: glTF
// composes T R S, so translation = t and rotation = R exactly; a transform
// that is not a rotation (shear, scale, reflection) has no TRS and is refused.
RigidMotion decompose_support(const FrameState& f, const std::string& rec_name) {
  if (f.support.empty()) return {Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity()};
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) R(i, j) = f.support[static_cast<std::size_t>(4 * i + j)];
    t[i] = f.support[static_cast<std::size_t>(4 * i + 3)];
  }
  const double off = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (off > 1e-4 || R.determinant() <= 0) {
    throw RecordingError(
        fmt::format("recording {}: frame {}: the support transform is not rigid (|R^T R - I| "
                    "= {:.3g}, det R = {:.6g}; expected a rotation and a translation)",
                    rec_name, f.frame, off, R.determinant()));
  }
  return {t, Eigen::Quaterniond(R).normalized()};
}

struct Keyframes {
  std::vector<float> times, weights, translations, rotations;
};

// The support's keyframes only `with_support`: without a support node the
// recorded transform moves nothing and is not checked.
Keyframes keyframes(const Session& s, double dt, bool with_support, const std::string& rec_name) {
  Keyframes k;
  const std::uint64_t first = s.frames.front().frame;
  Eigen::Quaterniond previous = Eigen::Quaterniond::Identity();
  for (const auto& f : s.frames) {
    k.times.push_back(static_cast<float>(static_cast<double>(f.frame - first) * dt));
    k.weights.insert(k.weights.end(), f.q_u.begin(), f.q_u.end());
    if (!with_support) continue;
    const RigidMotion m = decompose_support(f, rec_name);
    // q and -q are the same rotation; keeping neighbours in one hemisphere
    // stops importers that interpolate components (Blender) from flipping.
    Eigen::Quaterniond q = m.rotation;
    if (q.dot(previous) < 0) q.coeffs() = -q.coeffs();
    previous = q;
    k.translations.insert(k.translations.end(),
                          {float(m.translation.x()), float(m.translation.y()), float(m.translation.z())});
    k.rotations.insert(k.rotations.end(), {float(q.x()), float(q.y()), float(q.z()), float(q.w())});
  }
  return k;
}

void add_channel(tinygltf::Animation& a, int input, int output, int node, const char* path) {
  tinygltf::AnimationSampler sampler;
  sampler.input = input;
  sampler.output = output;
  sampler.interpolation = "LINEAR";
  a.samplers.push_back(sampler);
  tinygltf::AnimationChannel channel;
  channel.sampler = static_cast<int>(a.samplers.size()) - 1;
  channel.target_node = node;
  channel.target_path = path;
  a.channels.push_back(channel);
}

// One animation: q_u as the morph weights of every mesh with targets (eq. 7),
// the support node's translation and rotation (when there is one: no attached
// point, no node); keyframe times (frame - first frame) * dt. Returns the
// bytes of keyframe data it added; nothing when nothing would move.
std::size_t add_session_animation(GltfBuilder& g, const Session& s, double dt, int support_node,
                                  const std::vector<int>& morph_nodes, const std::string& rec_name) {
  if (morph_nodes.empty() && support_node < 0) return 0;
  const Keyframes k = keyframes(s, dt, support_node >= 0, rec_name);
  tinygltf::Animation a;
  a.name = fmt::format("instance {}", s.instance);
  const int times = g.add_floats(k.times, TINYGLTF_TYPE_SCALAR);
  std::size_t bytes = g.bytes_of(times);
  if (!morph_nodes.empty()) {
    const int weights = g.add_floats(k.weights, TINYGLTF_TYPE_SCALAR);
    for (const int node : morph_nodes) add_channel(a, times, weights, node, "weights");
    bytes += g.bytes_of(weights);
  }
  if (support_node >= 0) {
    const int translations = g.add_floats(k.translations, TINYGLTF_TYPE_VEC3);
    const int rotations = g.add_floats(k.rotations, TINYGLTF_TYPE_VEC4);
    add_channel(a, times, translations, support_node, "translation");
    add_channel(a, times, rotations, support_node, "rotation");
    bytes += g.bytes_of(translations) + g.bytes_of(rotations);
  }
  a.extras = tinygltf::Value(
      tinygltf::Value::Object{{"first_frame", tinygltf::Value(static_cast<double>(s.frames.front().frame))},
                              {"dt", tinygltf::Value(dt)},
                              {"instance", tinygltf::Value(static_cast<int>(s.instance))}});
  g.model().animations.push_back(std::move(a));
  return bytes;
}

// ---- assembling and writing ------------------------------------------------------

struct Built {
  tinygltf::Model model;
  std::size_t animation_bytes = 0;
  bool animated = false;  // a session was given and something in the file moves with it
  int dropped = 0;
  int triangles = 0;
};

// Scene graph: the world mesh and the support node (with the attached mesh as
// its child) at the root, and the scene camera; each only when it has
// triangles. Without a session the support stays at the identity: the support
// frame is the world frame at rest.
Built build_model(const ClientBasis& b, const ShLight& light, const std::optional<Session>& session,
                  double dt, const std::string& rec_name) {
  GltfBuilder g;
  const Parts parts = split_by_attachment(b);
  const VertexData data{mean_shape_normals(b), vertex_colours(b, light), add_unlit_material(g.model())};
  tinygltf::Scene scene;
  scene.name = b.scene;
  std::vector<int> morph_nodes;
  auto add_part = [&](const Part& part, const std::string& name) {
    tinygltf::Node node;
    node.name = name;
    node.mesh = add_mesh(g, b, part, data, name);
    const int index = g.add_node(std::move(node));
    if (part.deformable && b.rank_u > 0) morph_nodes.push_back(index);
    return index;
  };
  if (!parts.world.triangles.empty()) scene.nodes.push_back(add_part(parts.world, b.scene + " (world)"));
  int support_node = -1;
  if (!parts.attached.triangles.empty()) {
    tinygltf::Node support;
    support.name = "support";
    support.children.push_back(add_part(parts.attached, b.scene));
    support_node = g.add_node(std::move(support));
    scene.nodes.push_back(support_node);
  }
  if (const int camera = add_camera_node(g, b); camera >= 0) scene.nodes.push_back(camera);
  scene.extras = tinygltf::Value(tinygltf::Value::Object{
      {"package_content_hash", tinygltf::Value(fmt::format("{:016x}", b.content_hash))},
      {"r_u", tinygltf::Value(b.rank_u)}});
  g.model().scenes.push_back(std::move(scene));
  g.model().defaultScene = 0;
  Built built;
  if (session)
    built.animation_bytes = add_session_animation(g, *session, dt, support_node, morph_nodes, rec_name);
  built.animated = !g.model().animations.empty();
  built.dropped = parts.dropped;
  built.triangles = static_cast<int>((parts.world.triangles.size() + parts.attached.triangles.size()) / 3);
  built.model = std::move(g.model());
  return built;
}

std::string glb_bytes(const tinygltf::Model& model, const fs::path& out) {
  std::ostringstream stream;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, stream, /*prettyPrint=*/false, /*writeBinary=*/true)) {
    throw std::runtime_error(fmt::format("{}: tinygltf could not serialize the model", out.string()));
  }
  return stream.str();
}

// A temporary file next to `out`, renamed over it: an interrupted export never
// leaves a partial .glb that a viewer would half-load.
void write_atomically(const std::string& bytes, const fs::path& out) {
  const fs::path tmp = out.string() + fmt::format(".partial-{}", ::getpid());
  {
    std::ofstream file(tmp, std::ios::binary | std::ios::trunc);
    file.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    file.close();
    if (!file) {
      std::error_code ignored;
      fs::remove(tmp, ignored);
      throw std::runtime_error(fmt::format(
          "{}: cannot be written (expected a writable path in an existing folder)", out.string()));
    }
  }
  std::error_code ec;
  fs::rename(tmp, out, ec);
  if (ec) {
    std::error_code ignored;  // the rename's error is the one to report
    fs::remove(tmp, ignored);
    throw std::runtime_error(
        fmt::format("{}: cannot be written ({}; expected a path to a file in a writable folder)",
                    out.string(), ec.message()));
  }
}

void expect_glb_path(const fs::path& out) {
  std::string ext = out.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext != ".glb") {
    throw std::invalid_argument(
        fmt::format("-o {}: only binary glTF is written (expected a path ending in .glb)", out.string()));
  }
}

}  // namespace

GltfExportSummary export_gltf(const GltfExportOptions& o) {
  expect_glb_path(o.out);
  if (!o.light.empty()) light_probe(o.light);  // before the reading: a typo fails fast
  if (o.instance && !o.recording) {
    throw std::invalid_argument(
        "--instance needs --recording session.phcrec (a package alone has no instances)");
  }
  const core::ScenePackage package = core::read_package(o.package);
  const ClientBasis basis = basis_from_package(package, core::file_content_hash(o.package));
  const ShLight light = light_probe(!o.light.empty()       ? o.light
                                    : !basis.light.empty() ? basis.light
                                                           : "grace");
  std::optional<Session> session;
  if (o.recording) session = read_session(o, basis);
  const double dt = package.attributes.dt;
  const Built built = build_model(basis, light, session, dt, o.recording ? o.recording->string() : "");
  const std::string bytes = glb_bytes(built.model, o.out);
  write_atomically(bytes, o.out);

  GltfExportSummary s;
  s.scene = basis.scene;
  s.points = basis.points;
  s.triangles = built.triangles;
  s.dropped_triangles = built.dropped;
  s.rank_u = basis.rank_u;
  s.has_transfer = basis.has_transfer();
  s.file_bytes = bytes.size();
  s.animation_bytes = built.animation_bytes;
  s.animated = built.animated;
  if (session) {
    s.instance = session->instance;
    s.first_frame = session->frames.front().frame;
    s.frames = session->frames.size();
    s.duration_s = static_cast<double>(session->frames.back().frame - s.first_frame) * dt;
    s.recording_truncated = session->truncated;
  }
  return s;
}

std::string describe(const GltfExportSummary& s, const fs::path& out) {
  std::string text = fmt::format(
      "phasecast-export: wrote {} ({} bytes): scene '{}', {} points, {} triangles, {} morph targets "
      "(columns of U_u), colours from {}\n",
      out.string(), s.file_bytes, s.scene, s.points, s.triangles, s.rank_u,
      s.has_transfer ? "the mean transfer M̄" : "the grey diffuse fallback (no appearance model)");
  if (s.dropped_triangles > 0) {
    text += fmt::format(
        "phasecast-export: {} triangles join attached and world points and were left out (docs/gltf.md)\n",
        s.dropped_triangles);
  }
  if (s.recording_truncated) text += "phasecast-export: the recording's last record was truncated, ignored\n";
  if (s.instance && !s.animated) {
    text += fmt::format(
        "phasecast-export: no animation: nothing in scene '{}' moves (no exported mesh has deformable or "
        "attached points), so the {} frames of instance {} were read but not written\n",
        s.scene, s.frames, *s.instance);
  } else if (s.instance) {
    text += fmt::format(
        "phasecast-export: animation of instance {}: {} frames from frame {}, {:.2f} s; {} bytes of "
        "keyframes, "
        "{:.1f} bytes/frame (a vertex cache of the same session: {} bytes/frame)\n",
        *s.instance, s.frames, s.first_frame, s.duration_s, s.animation_bytes, s.animation_bytes_per_frame(),
        s.vertex_cache_bytes_per_frame());
  }
  return text;
}

}  // namespace phasecast::client
