#include "phasecast/precompute/appearance/transfer_rays.h"

#include <embree3/rtcore.h>
#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <map>
#include <stdexcept>
#include <vector>

namespace phasecast::precompute {
namespace {

using Vec3 = std::array<float, 3>;

Vec3 point(const MatrixXfR& P, std::uint32_t i) {
  return {P(i, 0), P(i, 1), P(i, 2)};
}

Vec3 face_normal(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 e1{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const Vec3 e2{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  return {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
}

float dot(const Vec3& a, const Vec3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// Exact position of a vertex as bits, so duplicated points of a double-sided
// surface compare equal without a tolerance.
using PositionKey = std::array<std::uint32_t, 3>;
PositionKey position_key(const Vec3& p) {
  PositionKey k;
  std::memcpy(k.data(), p.data(), sizeof(k));
  return k;
}

[[noreturn]] void embree_failure(RTCDevice device, const char* what) {
  throw std::runtime_error(
      fmt::format("Embree: {} failed (error code {})", what, static_cast<int>(rtcGetDeviceError(device))));
}

}  // namespace

struct RayCaster::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  // Per BVH triangle: its own points (front side) and the points of the
  // opposite-winding twin aligned to the same vertex order (back side), or
  // no_twin for a one-sided triangle.
  std::vector<std::array<std::uint32_t, 3>> front_points;
  std::vector<std::array<std::uint32_t, 3>> back_points;
  std::vector<Vec3> normals;  // unnormalized front normal per BVH triangle
  static constexpr std::uint32_t no_twin = std::numeric_limits<std::uint32_t>::max();

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  void merge_double_sided(const MatrixXfR& P, const MatrixXuR& F);
  void build(const MatrixXfR& P);
};

// Pairs coplanar triangles over the same three positions with opposite
// windings: the BVH holds one, the hit side picks which one's points to use.
void RayCaster::Impl::merge_double_sided(const MatrixXfR& P, const MatrixXuR& F) {
  std::map<std::array<PositionKey, 3>, std::uint32_t> open;  // sorted corner keys -> BVH triangle
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const std::array<std::uint32_t, 3> tri{F(f, 0), F(f, 1), F(f, 2)};
    const Vec3 a = point(P, tri[0]), b = point(P, tri[1]), c = point(P, tri[2]);
    const Vec3 n = face_normal(a, b, c);
    std::array<PositionKey, 3> key{position_key(a), position_key(b), position_key(c)};
    std::sort(key.begin(), key.end());
    const auto it = open.find(key);
    if (it != open.end() && back_points[it->second][0] == no_twin && dot(normals[it->second], n) < 0) {
      const auto g = it->second;
      for (int i = 0; i < 3; ++i) {
        const auto want = position_key(point(P, front_points[g][static_cast<size_t>(i)]));
        for (const auto q : tri) {
          if (position_key(point(P, q)) == want) back_points[g][static_cast<size_t>(i)] = q;
        }
      }
      continue;
    }
    open.emplace(key, static_cast<std::uint32_t>(front_points.size()));
    front_points.push_back(tri);
    back_points.push_back({no_twin, no_twin, no_twin});
    normals.push_back(n);
  }
}

void RayCaster::Impl::build(const MatrixXfR& P) {
  device = rtcNewDevice(nullptr);
  if (!device) throw std::runtime_error("Embree: rtcNewDevice failed");
  scene = rtcNewScene(device);
  if (!scene) embree_failure(device, "rtcNewScene");
  rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);  // no leaks through shared edges
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  if (!geom) embree_failure(device, "rtcNewGeometry");
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), static_cast<size_t>(P.rows())));
  auto* t = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(std::uint32_t), front_points.size()));
  if (!v || !t) {
    rtcReleaseGeometry(geom);
    embree_failure(device, "rtcSetNewGeometryBuffer");
  }
  std::memcpy(v, P.data(), sizeof(float) * static_cast<size_t>(P.size()));
  std::memcpy(t, front_points.data(), sizeof(std::uint32_t) * 3 * front_points.size());
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);
  if (rtcGetDeviceError(device) != RTC_ERROR_NONE) embree_failure(device, "rtcCommitScene");
}

RayCaster::RayCaster(const MatrixXfR& positions, const MatrixXuR& triangles)
    : impl_(std::make_unique<Impl>()) {
  impl_->merge_double_sided(positions, triangles);
  impl_->build(positions);
}

RayCaster::~RayCaster() = default;

int RayCaster::built_triangles() const {
  return static_cast<int>(impl_->front_points.size());
}

bool RayCaster::occluded(const Vec3& origin, const Vec3& dir, float t_far) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray{};
  ray.org_x = origin[0], ray.org_y = origin[1], ray.org_z = origin[2];
  ray.dir_x = dir[0], ray.dir_y = dir[1], ray.dir_z = dir[2];
  ray.tnear = 0;
  ray.tfar = t_far;
  ray.mask = std::numeric_limits<unsigned>::max();
  rtcOccluded1(impl_->scene, &context, &ray);
  return ray.tfar < 0;  // Embree sets tfar to -inf on a hit
}

RayHit RayCaster::closest(const Vec3& origin, const Vec3& dir) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh{};
  rh.ray.org_x = origin[0], rh.ray.org_y = origin[1], rh.ray.org_z = origin[2];
  rh.ray.dir_x = dir[0], rh.ray.dir_y = dir[1], rh.ray.dir_z = dir[2];
  rh.ray.tnear = 0;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.mask = std::numeric_limits<unsigned>::max();
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  RayHit hit;
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
  hit.hit = true;
  hit.t = rh.ray.tfar;
  const auto f = rh.hit.primID;
  // Embree's u, v weigh vertices 1 and 2 of the triangle as it was given.
  hit.weights = {1 - rh.hit.u - rh.hit.v, rh.hit.u, rh.hit.v};
  if (dot(impl_->normals[f], dir) < 0) {
    hit.front = true;
    hit.points = impl_->front_points[f];
  } else if (impl_->back_points[f][0] != Impl::no_twin) {
    hit.front = true;
    hit.points = impl_->back_points[f];
  }
  return hit;
}

}  // namespace phasecast::precompute
