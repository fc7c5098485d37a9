#include "render_target.h"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <Eigen/Geometry>

#include <cmath>
#include <ostream>
#include <stdexcept>

namespace phasecast::client {

Camera camera_for(const Camera& view, const RenderOptions& o) {
  Camera c = view;
  if (!o.eye.empty()) c.eye = parse_vector3(o.eye, "--eye");
  if (!o.target.empty()) c.target = parse_vector3(o.target, "--target");
  if (!o.up.empty()) c.up = parse_vector3(o.up, "--up");
  if (o.fov_y_deg) {
    if (!(*o.fov_y_deg > 0 && *o.fov_y_deg < 180)) {
      throw std::invalid_argument(
          fmt::format("--fov {} is invalid (expected degrees in (0, 180))", *o.fov_y_deg));
    }
    c.fov_y_deg = *o.fov_y_deg;
  }
  const Eigen::Vector3f direction = c.target - c.eye;
  if (!(direction.norm() > 0)) {
    throw std::invalid_argument("camera eye and target coincide (expected distinct --eye and --target)");
  }
  if (!(direction.normalized().cross(c.up).norm() > 1e-6f)) {
    throw std::invalid_argument(
        "camera --up is parallel to the view direction (expected a vector across it)");
  }
  return c;
}

ShLight light_for(const ClientBasis& basis, const RenderOptions& o) {
  if (!o.light.empty()) return light_probe(o.light);
  if (basis.light.empty()) return light_probe("grace");
  try {
    return light_probe(basis.light);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(fmt::format("scene '{}' [view] light: {}", basis.scene, e.what()));
  }
}

void RenderTarget::make_renderer(const ClientBasis& basis, const RenderOptions& o) {
  renderer = std::make_unique<LowRankRenderer>(*backend, basis, o.width, o.height,
                                               o.half ? BasisPrecision::float16 : BasisPrecision::float32);
  renderer->set_light(light_for(basis, o));
  view_ = scene_camera(basis);
  rest_ = rest_bounds(basis);
  renderer->set_exposure(o.exposure.value_or(basis.exposure.value_or(1.0f)));
  renderer->set_backdrop(o.backdrop.value_or(basis.floor) ? Backdrop::ground : Backdrop::none);
  set_instances(instances_, o);
}

void RenderTarget::set_instances(int count, const RenderOptions& o) {
  instances_ = count;
  const auto placements =
      o.layout ? layout_placements(layout_, *o.layout, count) : grid_placements(rest_, count);
  renderer->set_placements(placements);
  renderer->set_camera(camera_for(group_camera(view_, rest_, placements), o));
}

void report(std::ostream& log, const RenderStats& s, int width, int height) {
  fmt::print(
      log, "phasecast-render: {} frames at {}x{}: {:.1f} frames/s render-only, {:.1f} frames/s end-to-end\n",
      s.frames, width, height, s.render_fps(), s.end_to_end_fps());
}

void report_progress(std::ostream& log, const RenderStats& s, std::uint64_t frame, std::uint64_t total) {
  static thread_local double next_report = 2;
  if (s.frames == 1) next_report = 2;
  if (s.wall_seconds < next_report) return;
  next_report = s.wall_seconds + 2;
  fmt::print(log, "phasecast-render: frame {}: {} rendered{} ({:.1f} frames/s)\n", frame, s.frames,
             total ? fmt::format(" of {}", total) : std::string(), s.end_to_end_fps());
  log.flush();
}

}  // namespace phasecast::client
