#pragma once
// What a render session draws with: the backend, the renderer holding one set
// of bases, and the outputs (PNG frames, video, vertex dump); the camera the
// options ask for; and the progress lines both sessions print.

#include "phasecast/client/client_basis.h"
#include "phasecast/client/frame_output.h"
#include "phasecast/client/layout.h"
#include "phasecast/client/low_rank_renderer.h"
#include "phasecast/client/render_app.h"
#include "phasecast/client/render_backend.h"
#include "phasecast/client/sh_light.h"

#include <cstdint>
#include <iosfwd>
#include <memory>

namespace phasecast::client {

// `view` (the scene's camera, or the group's) with the options' --eye,
// --target, --up and --fov. Throws std::invalid_argument naming the option
// that makes no camera.
Camera camera_for(const Camera& view, const RenderOptions& o);
inline Camera camera_for(const ClientBasis& basis, const RenderOptions& o) {
  return camera_for(scene_camera(basis), o);
}

// The light the options name, else the scene's, else grace.
ShLight light_for(const ClientBasis& basis, const RenderOptions& o);

// Backend, renderer and outputs. The renderer holds one set of bases; the
// backend and the outputs last the whole run.
struct RenderTarget {
  std::unique_ptr<RenderBackend> backend;
  std::unique_ptr<LowRankRenderer> renderer;
  std::unique_ptr<FrameOutput> output;

  // `frame_rate`: frames per second of the stream (1 / dt), for the video.
  // `instances`: how many instances of the scene stand in the view, on the
  // default grid.
  RenderTarget(const ClientBasis& basis, const RenderOptions& o, double frame_rate, int instances = 1)
      : instances_(instances) {
    if (o.layout) layout_ = read_layout(*o.layout);
    backend = make_render_backend(o.backend, o.width, o.height);
    make_renderer(basis, o);
    OutputOptions out;
    out.png_dir = o.out_dir;
    out.video = o.video;
    out.video_fps = frame_rate > 0 && std::isfinite(frame_rate) ? frame_rate : 60;
    out.dump_frame = o.dump_frame;
    out.dump_path = o.dump_path;
    output = std::make_unique<FrameOutput>(*renderer, o.width, o.height, out);
  }

  // New bases (the server came back with another package): a new renderer on
  // the same context; the window, the PNG numbering and the video go on.
  void replace_bases(const ClientBasis& basis, const RenderOptions& o) {
    renderer.reset();  // frees the old bases' GPU buffers first
    make_renderer(basis, o);
    output->set_renderer(*renderer);
  }

  // `count` instances on the default grid from now on; the camera takes in
  // all of them unless the options place it.
  void set_instances(int count, const RenderOptions& o);
  int instances() const { return instances_; }

 private:
  void make_renderer(const ClientBasis& basis, const RenderOptions& o);

  int instances_ = 1;
  std::vector<Eigen::Matrix4f> layout_;  // --layout's placements; empty: the default grid
  Camera view_;                          // the scene's own camera
  Eigen::AlignedBox3f rest_;             // of x_bar: the grid's spacing
};

// "phasecast-render: N frames at WxH: ... frames/s render-only, ... end-to-end".
void report(std::ostream& log, const RenderStats& s, int width, int height);

// A line every two seconds on long runs: frames done (of how many) and the rate.
void report_progress(std::ostream& log, const RenderStats& s, std::uint64_t frame, std::uint64_t total);

}  // namespace phasecast::client
