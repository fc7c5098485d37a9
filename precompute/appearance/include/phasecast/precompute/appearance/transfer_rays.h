#pragma once
// Ray casting against a static triangle mesh with Embree 3 (robust mode), for
// the transfer precompute (§4.1). Embree stays private: this header exposes
// only what the transfer code and the benchmark need.

#include "phasecast/core/eigen_types.h"

#include <array>
#include <cstdint>
#include <memory>

namespace phasecast::precompute {

// What a closest-hit ray saw. A double-sided surface (two coplanar triangles
// with opposite windings) is built once into the BVH; the hit resolves to the
// triangle whose front face the ray sees. A hit on the back of a one-sided
// triangle has `front` false and no points.
struct RayHit {
  bool hit = false;
  bool front = false;
  float t = 0;
  std::array<std::uint32_t, 3> points{};  // scene points of the seen triangle
  std::array<float, 3> weights{};         // barycentric weights of those points
};

class RayCaster {
 public:
  //   @param[in] positions  #S by 3 points
  //   @param[in] triangles  #F by 3 point indices (validated by the caller)
  RayCaster(const MatrixXfR& positions, const MatrixXuR& triangles);
  ~RayCaster();
  RayCaster(const RayCaster&) = delete;
  RayCaster& operator=(const RayCaster&) = delete;

  // Whether any triangle lies on the ray origin + t dir, t in (0, t_far). Thread-safe.
  bool occluded(const std::array<float, 3>& origin, const std::array<float, 3>& dir,
                float t_far = 1e30f) const;
  // The nearest triangle on the ray, resolved to the side the ray sees. Thread-safe.
  RayHit closest(const std::array<float, 3>& origin, const std::array<float, 3>& dir) const;

  // Triangles in the BVH after merging double-sided pairs.
  int built_triangles() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phasecast::precompute
