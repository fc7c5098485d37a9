#pragma once
// The view: from the scene metadata (package attribute / SceneInfo.camera:
// eye, target, up, fov_y_deg) when present, else framed around the rest mesh;
// command-line overrides replace single fields.

#include "phasecast/client/client_basis.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <string>
#include <vector>

namespace phasecast::client {

struct Camera {
  Eigen::Vector3f eye{0, 0, 3};
  Eigen::Vector3f target{0, 0, 0};
  Eigen::Vector3f up{0, 1, 0};
  float fov_y_deg = 40;
};

// The scene's camera, or one looking down -z at the bounding box of x_bar.
Camera scene_camera(const ClientBasis& basis);

// Perspective projection times look-at view, column-major for GL; near and
// far planes from the distance to the target and the scene radius.
Eigen::Matrix4f view_projection(const Camera& camera, int width, int height, float scene_radius);
// The same view with the given near and far plane distances (0 < near < far).
Eigen::Matrix4f view_projection(const Camera& camera, int width, int height, float near_plane,
                                float far_plane);

// Radius of the bounding sphere of x_bar about its bounding-box centre.
float scene_radius(const ClientBasis& basis);

// The bounding box of x_bar.
Eigen::AlignedBox3f rest_bounds(const ClientBasis& basis);

// Where `count` instances of a scene whose rest mesh fills `rest` stand on
// the default grid (instance frame -> world): columns along x, rows going
// back along -z, as square as the count allows, 2.2 scene radii apart (a
// door swung open or a leaf in the wind stays clear of its neighbours),
// centred on the scene's own place. Throws std::invalid_argument below 1.
std::vector<Eigen::Matrix4f> grid_placements(const Eigen::AlignedBox3f& rest, int count);

// `view` (the scene's camera) moved with the group's centre and pulled back
// along its own direction until every placed instance is in the picture.
Camera group_camera(const Camera& view, const Eigen::AlignedBox3f& rest,
                    const std::vector<Eigen::Matrix4f>& placements);

// Parses "x,y,z"; throws std::invalid_argument naming `what` otherwise.
Eigen::Vector3f parse_vector3(const std::string& text, const std::string& what);

// Parses "WxH" (e.g. 1280x720); throws std::invalid_argument otherwise.
std::array<int, 2> parse_size(const std::string& text);

}  // namespace phasecast::client
