#include "phasecast/client/camera.h"

#include <fmt/format.h>
#include <Eigen/Geometry>

#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace phasecast::client {
Eigen::AlignedBox3f rest_bounds(const ClientBasis& b) {
  Eigen::AlignedBox3f box;
  for (std::size_t v = 0; v < static_cast<std::size_t>(b.points); ++v) {
    box.extend(Eigen::Vector3f(b.mean_shape[3 * v], b.mean_shape[3 * v + 1], b.mean_shape[3 * v + 2]));
  }
  return box;
}

float scene_radius(const ClientBasis& b) {
  const auto box = rest_bounds(b);
  return std::max(0.5f * box.diagonal().norm(), 1e-3f);
}

Camera scene_camera(const ClientBasis& b) {
  Camera c;
  if (b.camera) {
    const auto& a = *b.camera;
    c.eye = {a[0], a[1], a[2]};
    c.target = {a[3], a[4], a[5]};
    c.up = {a[6], a[7], a[8]};
    c.fov_y_deg = a[9];
    return c;
  }
  const auto box = rest_bounds(b);
  c.target = box.center();
  const float distance =
      scene_radius(b) / std::tan(0.5f * c.fov_y_deg * std::numbers::pi_v<float> / 180) * 1.1f;
  c.eye = c.target + Eigen::Vector3f(0, 0, distance);
  return c;
}

std::vector<Eigen::Matrix4f> grid_placements(const Eigen::AlignedBox3f& rest, int count) {
  if (count < 1) throw std::invalid_argument(fmt::format("{} instances (expected at least 1)", count));
  const int columns = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(count))));
  const int rows = (count + columns - 1) / columns;
  const float spacing = 2.2f * std::max(0.5f * rest.diagonal().norm(), 1e-3f);
  std::vector<Eigen::Matrix4f> placements;
  for (int i = 0; i < count; ++i) {
    Eigen::Matrix4f p = Eigen::Matrix4f::Identity();
    p(0, 3) = spacing * (static_cast<float>(i % columns) - 0.5f * static_cast<float>(columns - 1));
    p(2, 3) = -spacing * (static_cast<float>(i / columns) - 0.5f * static_cast<float>(rows - 1));
    placements.push_back(p);
  }
  return placements;
}

namespace {
constexpr float kGroupElevationDeg = 30;
}  // namespace

Camera group_camera(const Camera& view, const Eigen::AlignedBox3f& rest,
                    const std::vector<Eigen::Matrix4f>& placements) {
  Camera c = view;
  if (placements.size() <= 1 && (placements.empty() || placements[0].isIdentity())) return c;
  Eigen::AlignedBox3f group;
  for (const auto& p : placements) {
    for (int k = 0; k < 8; ++k) {
      const auto corner = rest.corner(static_cast<Eigen::AlignedBox3f::CornerType>(k));
      group.extend((p * corner.homogeneous()).head<3>());
    }
  }
  // The scene's own view direction, raised to look down on the rows at
  // least kGroupElevation (from level the front row hides the others), from a
  // distance that fits the group's bounding sphere in the field of view.
  Eigen::Vector3f back = (c.eye - c.target).normalized();
  const Eigen::Vector3f up = c.up.normalized();
  const float min_elevation = std::sin(kGroupElevationDeg * std::numbers::pi_v<float> / 180);
  if (back.dot(up) < min_elevation) {
    Eigen::Vector3f level = back - back.dot(up) * up;
    if (level.norm() < 1e-6f) level = up.unitOrthogonal();
    back = level.normalized() * std::sqrt(1 - min_elevation * min_elevation) + min_elevation * up;
  }
  const Eigen::Vector3f shift = group.center() - rest.center();
  c.target += shift;
  // The nearest eye on that line that sees every corner of the group's box
  // within the vertical field of view (and as wide, for square or wider images).
  const Eigen::Vector3f forward = -back;
  const Eigen::Vector3f side = forward.cross(up).normalized();
  const Eigen::Vector3f above = side.cross(forward);
  const float t = std::tan(0.5f * c.fov_y_deg * std::numbers::pi_v<float> / 180);
  float distance = 0;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3f p = group.corner(static_cast<Eigen::AlignedBox3f::CornerType>(k)) - c.target;
    const float across = std::max(std::abs(p.dot(side)), std::abs(p.dot(above)));
    distance = std::max(distance, across / t - p.dot(forward));
  }
  c.eye = c.target + back * (1.15f * distance);  // room for motion beyond the rest boxes
  return c;
}

Eigen::Matrix4f view_projection(const Camera& c, int width, int height, float radius) {
  // Depth range from the distance to the target and the scene size, so any
  // scale of scene keeps depth precision.
  const float distance = (c.target - c.eye).norm();
  const float far_plane = distance + 4 * radius;
  const float near_plane = std::max(distance - 4 * radius, far_plane * 1e-3f);
  return view_projection(c, width, height, near_plane, far_plane);
}

Eigen::Matrix4f view_projection(const Camera& c, int width, int height, float near_plane, float far_plane) {
  const Eigen::Vector3f f = (c.target - c.eye).normalized();
  const Eigen::Vector3f s = f.cross(c.up).normalized();
  const Eigen::Vector3f u = s.cross(f);
  Eigen::Matrix4f view = Eigen::Matrix4f::Identity();
  view.block<1, 3>(0, 0) = s.transpose();
  view.block<1, 3>(1, 0) = u.transpose();
  view.block<1, 3>(2, 0) = -f.transpose();
  view(0, 3) = -s.dot(c.eye);
  view(1, 3) = -u.dot(c.eye);
  view(2, 3) = f.dot(c.eye);

  const float t = std::tan(0.5f * c.fov_y_deg * std::numbers::pi_v<float> / 180);
  const float aspect = static_cast<float>(width) / static_cast<float>(height);
  Eigen::Matrix4f proj = Eigen::Matrix4f::Zero();
  proj(0, 0) = 1 / (aspect * t);
  proj(1, 1) = 1 / t;
  proj(2, 2) = -(far_plane + near_plane) / (far_plane - near_plane);
  proj(2, 3) = -2 * far_plane * near_plane / (far_plane - near_plane);
  proj(3, 2) = -1;
  return proj * view;
}

Eigen::Vector3f parse_vector3(const std::string& text, const std::string& what) {
  std::istringstream in(text);
  Eigen::Vector3f v;
  char comma1 = 0, comma2 = 0;
  if (!(in >> v.x() >> comma1 >> v.y() >> comma2 >> v.z()) || comma1 != ',' || comma2 != ',' ||
      !(in >> std::ws).eof() || !v.allFinite()) {
    throw std::invalid_argument(
        fmt::format("{} '{}' is invalid (expected three finite numbers x,y,z)", what, text));
  }
  return v;
}

std::array<int, 2> parse_size(const std::string& text) {
  std::istringstream in(text);
  int w = 0, h = 0;
  char x = 0;
  if (!(in >> w >> x >> h) || (x != 'x' && x != 'X') || !(in >> std::ws).eof() || w <= 0 || h <= 0 ||
      w > 16384 || h > 16384) {
    throw std::invalid_argument(
        fmt::format("--size '{}' is invalid (expected WIDTHxHEIGHT, e.g. 1280x720)", text));
  }
  return {w, h};
}

}  // namespace phasecast::client
