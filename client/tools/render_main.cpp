// phasecast-render: the thin render client (§5.3). See docs/client.md.

#include "phasecast/client/camera.h"
#include "phasecast/client/curve_options.h"
#include "phasecast/client/render_app.h"
#include "phasecast/client/render_backend.h"
#include "phasecast/client/sh_light.h"
#include "phasecast/client/simulation_view.h"
#include "phasecast/core/progress.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <iostream>

namespace {

// Ctrl-C or a TERM ends the session after the frame in hand: the video is
// finished and the summary printed.
std::atomic<bool> g_interrupted{false};

extern "C" void on_interrupt(int) {
  g_interrupted = true;
}

// --simulation: the orbit store's frames as they were simulated, chunk by chunk.
void render_simulation(const phasecast::client::RenderOptions& o, const std::string& store,
                       const std::string& scene_file) {
  using namespace phasecast::client;
  phasecast::core::ProgressBar bar("rest transfer");
  const SimulationView view(
      store, scene_file.empty() ? std::nullopt : std::optional<std::filesystem::path>(scene_file),
      [&bar, last = std::string()](const char* pass, long done, long total) mutable {
        if (pass != last) bar.restart(fmt::format("rest transfer, {}", last = pass));
        bar.update(done, total);
      });
  bar.finish();
  FrameChunks chunks;
  chunks.source = store;
  chunks.description = fmt::format("simulation {} of scene '{}' ({}), drawn as simulated", store,
                                   view.scene(), view.scene_file().string());
  chunks.dt = view.dt();
  chunks.frames = o.max_frames > 0 ? std::min<std::uint64_t>(o.max_frames, view.frames()) : view.frames();
  chunks.chunks = view.chunks(chunks.frames);
  chunks.chunk = [&view, &chunks](int index) { return view.chunk(index, chunks.frames); };
  render_chunks(o, chunks, std::cout, g_interrupted);
}

}  // namespace

int main(int argc, char** argv) {
  using phasecast::client::RenderOptions;
  RenderOptions o;
  CLI::App app{
      "phasecast-render: renders a Phasecast scene from its reduced state (q_u, q_a) with the bases "
      "on the GPU. Frame sources: a server (--connect), a recording (--replay with --package), the "
      "package's own phase portrait (--package [--play-irf I]) or a simulation (--simulation run.h5)."};
  std::string size = "512x512";
  std::vector<std::string> dump;
  std::uint32_t instance = 0;
  int play_irf = 0;
  std::string replay, package, out, video;
  float fov = 0;
  app.add_option("--connect", o.connect, "command endpoint of phasecast-server, e.g. tcp://host:5555");
  auto* instance_opt = app.add_option("--instance", instance,
                                      "instance to follow (default: first instance of the "
                                      "first scene), or to take from a --replay recording");
  std::string instances;
  app.add_option("--instances", instances,
                 "several instances of one scene in one view, on a grid: a list (1,2,3), or all (every "
                 "instance of the first scene); network, or --replay with a list");
  std::string layout;
  app.add_option(
      "--layout", layout,
      "JSON file placing the instances in view: {\"placements\": [{\"translate\": [x, y, z], "
      "\"rotate_y_deg\": a}, ...]}, one entry per instance in id (or copy) order (default: a grid)");
  app.add_option("--create", o.create, "create a new instance of this scene and follow it (--count of them)");
  app.add_option("--count", o.count,
                 "with --create: make this many instances and draw them in one view; local mode: draw this "
                 "many copies of the IRF, each further on in it (default 1)");
  app.add_option("--replay", replay, "render a recorded stream (needs --package)");
  std::string simulation, scene_file;
  auto* simulation_opt = app.add_option(
      "--simulation", simulation,
      "render an orbit store (phasecast-precompute simulate's output) as it was simulated: the "
      "scene's points, colours and light, nothing reduced");
  app.add_option("--scene-file", scene_file,
                 "with --simulation: the scene file (default: the one the store was made from)")
      ->needs(simulation_opt);
  app.add_option("--package", package, "scene package (.h5): local mode, or the bases for --replay");
  auto* irf_opt =
      app.add_option("--play-irf", play_irf, "local mode: play this IRF of the package (default 0)");
  app.add_option("--backend", o.backend,
                 fmt::format("render backend: {} (default osmesa)",
                             fmt::join(phasecast::client::render_backend_names(), ", ")));
  app.add_option("--size", size, "image size WIDTHxHEIGHT (default 512x512)");
  app.add_option("--frames", o.max_frames, "stop after this many frames (0: all / until interrupted)");
  app.add_option(
      "--out", out,
      "write PNG frames into this directory: frame_%06d.png (the server's frame numbers); when "
      "frame numbers start again (a restarted server), restart01_frame_%06d.png, restart02_..., so "
      "no file is replaced");
  app.add_option("--video", video, "write an MP4 through ffmpeg");
  app.add_option("--light", o.light,
                 fmt::format("SH light probe: {} (default: the scene's [view] light, else grace)",
                             fmt::join(phasecast::client::light_probe_names(), ", ")));
  std::string backdrop;
  app.add_option("--backdrop", backdrop,
                 "on|off: a ground plane at the scene's floor height (default: its rest mesh's lowest "
                 "point), fading into a dark grey background (default: on unless the scene's [view] says "
                 "floor = \"none\"); off: the scene alone on a near-black background. The scene's own "
                 "evaluation (--dump-vertices) is the same either way");
  app.add_flag(
      "--half", o.half,
      "upload U_u and U_a as 16-bit floats: half their bytes on the GPU, about 5e-4 of the displacement "
      "in error (docs/performance-client.md)");
  float exposure = 1;
  auto* exposure_opt = app.add_option(
      "--exposure", exposure, "multiplies the exit radiance before display (default: the scene's, else 1)");
  app.add_option("--dump-vertices", dump,
                 "FRAME PATH: write the GPU-computed positions and radiance of that frame "
                 "(.npy or .csv)")
      ->expected(2);
  app.add_option("--eye", o.eye, "camera position x,y,z (default: scene metadata)");
  app.add_option("--target", o.target, "camera target x,y,z");
  app.add_option("--up", o.up, "camera up vector x,y,z");
  auto* fov_opt = app.add_option("--fov", fov, "vertical field of view in degrees");
  app.add_option("--frame-timeout", o.frame_timeout_s,
                 "network: seconds without frames before reconnecting (default 3)");
  app.add_option("--give-up-after", o.give_up_after_s,
                 "network: exit with status 1 when no frame could be rendered for this many seconds (server "
                 "gone, no frames, only rejected frames; default 60)");
  app.add_option("--request-timeout", o.request_timeout_s,
                 "network: seconds to wait for each reply (default 2)");
  phasecast::client::CurveKeyFiles keys;
  phasecast::client::add_curve_options(app, keys, "network: ");
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-render"))
    return *status;
  try {
    const auto wh = phasecast::client::parse_size(size);
    o.width = wh[0];
    o.height = wh[1];
    if (!backdrop.empty()) o.backdrop = phasecast::client::parse_on_off(backdrop, "--backdrop");
    if (*exposure_opt) o.exposure = exposure;
    if (*instance_opt) o.instance = instance;
    if (!layout.empty()) o.layout = layout;
    if (instances == "all") {
      o.all_instances = true;
    } else if (!instances.empty()) {
      o.instances = phasecast::client::parse_instance_list(instances);
    }
    if (*irf_opt) o.play_irf = play_irf;
    if (*fov_opt) o.fov_y_deg = fov;
    if (!replay.empty()) o.replay = replay;
    if (!package.empty()) o.package = package;
    if (!out.empty()) o.out_dir = out;
    if (!video.empty()) o.video = video;
    o.server_key = keys.server_key;
    o.client_key = keys.client_key;
    if (!dump.empty()) {
      std::size_t used = 0;
      try {
        o.dump_frame = std::stoull(dump[0], &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != dump[0].size()) {
        throw std::invalid_argument(fmt::format(
            "--dump-vertices frame '{}' is invalid (expected a frame number, then out.npy or out.csv)",
            dump[0]));
      }
      o.dump_path = dump[1];
    }
    // Progress and the summary go to stdout; stderr carries only the error line.
    std::signal(SIGINT, on_interrupt);
    std::signal(SIGTERM, on_interrupt);
    if (!simulation.empty()) {
      render_simulation(o, simulation, scene_file);
    } else {
      phasecast::client::run_render(o, std::cout, g_interrupted);
    }
  } catch (const std::exception& e) {
    std::cerr << "phasecast-render: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
