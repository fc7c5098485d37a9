#pragma once
// The backdrop's ground: a floor under the rest mesh that fades into the flat
// background a few scene radii away (shaders/backdrop.vert, backdrop.frag),
// lit like the scene. Drawn first, with no depth test and no depth written,
// so the scene always covers it; seen from above only.

#include "gl_program.h"
#include "phasecast/client/camera.h"
#include "phasecast/client/client_basis.h"
#include "phasecast/client/sh_light.h"

#include <Eigen/Core>

namespace phasecast::client::detail {

class GroundPlane {
 public:
  // Under the rest mesh (x-bar; what scene_camera frames too): its lowest y,
  // centred under its bounding box.
  GroundPlane(const GlFunctions& gl, const ClientBasis& basis, float scene_radius);

  // Many instances: the ground centred under them (x, z) and reaching this
  // many radii of the group.
  void cover(const Eigen::Vector2f& centre, float radius);

  void draw(const Camera& camera, int width, int height, const ShLight& light, float exposure) const;

 private:
  const GlFunctions& gl_;
  float radius_;
  float height_ = 0;
  Eigen::Vector2f centre_ = Eigen::Vector2f::Zero();
  GlProgram program_;
  VertexArray vao_;  // empty: the square's vertices come from gl_VertexID
};

}  // namespace phasecast::client::detail
