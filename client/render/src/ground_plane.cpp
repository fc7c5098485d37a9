#include "ground_plane.h"

#include "phasecast/client/embedded_shaders.h"
#include "phasecast/client/low_rank_renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace phasecast::client::detail {
namespace {

// Half the side of the ground square, in scene radii: its fade
// (shaders/backdrop.frag) is below 1/255 there.
constexpr float kGroundExtent = 6.5f;

// Linear radiance -> display value, clamped: what radiance.frag does per pixel.
float srgb_encode(double linear) {
  const double l = std::clamp(linear, 0.0, 1.0);
  return static_cast<float>(l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1 / 2.4) - 0.055);
}

}  // namespace

GroundPlane::GroundPlane(const GlFunctions& gl, const ClientBasis& basis, float scene_radius)
    : gl_(gl),
      radius_(scene_radius),
      program_(
          link_program(gl, shaders::backdrop_vert, "backdrop.vert", shaders::backdrop_frag, "backdrop.frag")),
      vao_(gl) {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = -lo;
  for (std::size_t v = 0; v < static_cast<std::size_t>(basis.points); ++v) {
    const Eigen::Vector3f x(basis.mean_shape[3 * v], basis.mean_shape[3 * v + 1],
                            basis.mean_shape[3 * v + 2]);
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  height_ = basis.floor_height.value_or(lo.y());
  centre_ = {0.5f * (lo.x() + hi.x()), 0.5f * (lo.z() + hi.z())};
}

void GroundPlane::cover(const Eigen::Vector2f& centre, float radius) {
  centre_ = centre;
  radius_ = radius;
}

void GroundPlane::draw(const Camera& camera, int width, int height, const ShLight& light,
                       float exposure) const {
  if (!(camera.eye.y() > height_)) return;
  // The square's corners bound its view depths: near and far planes around them.
  const float extent = kGroundExtent * radius_;
  const Eigen::Vector3f forward = (camera.target - camera.eye).normalized();
  float nearest = std::numeric_limits<float>::max(), farthest = 0;
  for (const float dx : {-extent, extent}) {
    for (const float dz : {-extent, extent}) {
      const Eigen::Vector3f corner(centre_.x() + dx, height_, centre_.y() + dz);
      const float depth = (corner - camera.eye).dot(forward);
      nearest = std::min(nearest, depth);
      farthest = std::max(farthest, depth);
    }
  }
  if (!(farthest > 0)) return;  // all of it behind the camera
  const float far_plane = 1.01f * farthest;
  const float near_plane = std::max(0.99f * nearest, 1e-4f * far_plane);
  gl_.glDisable(GL_DEPTH_TEST);
  gl_.glDisable(GL_CULL_FACE);
  program_.use();
  const Eigen::Matrix4f vp = view_projection(camera, width, height, near_plane, far_plane);
  gl_.glUniformMatrix4fv(program_.uniform("view_projection"), 1, GL_FALSE, vp.data());
  gl_.glUniform1f(program_.uniform("ground_height"), height_);
  gl_.glUniform2f(program_.uniform("ground_centre"), centre_.x(), centre_.y());
  gl_.glUniform1f(program_.uniform("ground_extent"), extent);
  gl_.glUniform1f(program_.uniform("scene_radius"), radius_);
  const auto floor = diffuse_radiance(light, Eigen::Vector3d::UnitY(), kGroundAlbedo);
  for (const auto& [name, scale] : {std::pair{"floor_colour", 1.0}, std::pair{"floor_dark", 0.88}}) {
    gl_.glUniform3f(program_.uniform(name), srgb_encode(scale * exposure * floor[0]),
                    srgb_encode(scale * exposure * floor[1]), srgb_encode(scale * exposure * floor[2]));
  }
  gl_.glUniform3f(program_.uniform("background"), kBackdropBackground[0], kBackdropBackground[1],
                  kBackdropBackground[2]);
  gl_.glBindVertexArray(vao_.get());
  gl_.glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
  gl_.glBindVertexArray(0);
}

}  // namespace phasecast::client::detail
