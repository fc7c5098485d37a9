#include "phasecast/client/render_app.h"

#include "phasecast/client/frame_output.h"
#include "phasecast/client/frame_sources.h"
#include "phasecast/client/network.h"
#include "phasecast/core/hash.h"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <ostream>
#include <thread>

namespace phasecast::client {
namespace {

std::atomic<bool> g_interrupted{false};

extern "C" void on_interrupt(int) {
  g_interrupted = true;
}

void check_source(const RenderOptions& o) {
  const int sources = (!o.connect.empty() ? 1 : 0) + (o.replay ? 1 : 0) + (o.package && !o.replay ? 1 : 0);
  if (sources != 1) {
    throw std::invalid_argument(
        "choose one frame source (expected --connect tcp://host:5555, --replay stream.rec "
        "--package p.h5, or --package p.h5 [--play-irf I])");
  }
  if (o.replay && !o.package) {
    throw std::invalid_argument("--replay needs --package p.h5: a recording holds frames, not the bases");
  }
  if (o.play_irf && (!o.connect.empty() || o.replay)) {
    throw std::invalid_argument("--play-irf is for local mode (--package without --replay or --connect)");
  }
  if (!o.create.empty() && o.connect.empty()) {
    throw std::invalid_argument("--create needs --connect tcp://host:5555");
  }
  if (o.instance && o.connect.empty() && !o.replay) {
    throw std::invalid_argument("--instance needs --connect tcp://host:5555 or --replay stream.rec");
  }
  if (o.instance && !o.create.empty()) throw std::invalid_argument("give --instance or --create, not both");
  for (const auto& [name, value] :
       {std::pair{"--frame-timeout", o.frame_timeout_s}, std::pair{"--request-timeout", o.request_timeout_s},
        std::pair{"--give-up-after", o.give_up_after_s}}) {
    if (!(value > 0) || !std::isfinite(value)) {
      throw std::invalid_argument(
          fmt::format("{} {} is invalid (expected a positive number of seconds)", name, value));
    }
  }
  if (!(o.exposure > 0) || !std::isfinite(o.exposure)) {
    throw std::invalid_argument(
        fmt::format("--exposure {} is invalid (expected a positive number)", o.exposure));
  }
}

Camera camera_for(const ClientBasis& basis, const RenderOptions& o) {
  Camera c = scene_camera(basis);
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
  const Eigen::Vector3f view = c.target - c.eye;
  if (!(view.norm() > 0)) {
    throw std::invalid_argument("camera eye and target coincide (expected distinct --eye and --target)");
  }
  if (!(view.normalized().cross(c.up).norm() > 1e-6f)) {
    throw std::invalid_argument(
        "camera --up is parallel to the view direction (expected a vector across it)");
  }
  return c;
}

// Backend, renderer and outputs for one set of bases.
struct RenderTarget {
  std::unique_ptr<RenderBackend> backend;
  std::unique_ptr<LowRankRenderer> renderer;
  std::unique_ptr<FrameOutput> output;

  // `frame_rate`: frames per second of the stream (1 / dt), for the video.
  RenderTarget(const ClientBasis& basis, const RenderOptions& o, const ShLight& light, double frame_rate) {
    backend = make_render_backend(o.backend, o.width, o.height);
    renderer = std::make_unique<LowRankRenderer>(*backend, basis, o.width, o.height);
    renderer->set_light(light);
    renderer->set_camera(camera_for(basis, o));
    renderer->set_exposure(o.exposure);
    OutputOptions out;
    out.png_dir = o.out_dir;
    out.video = o.video;
    out.video_fps = frame_rate > 0 && std::isfinite(frame_rate) ? frame_rate : 60;
    out.dump_frame = o.dump_frame;
    out.dump_path = o.dump_path;
    output = std::make_unique<FrameOutput>(*renderer, o.width, o.height, out);
  }
};

void report(std::ostream& log, const RenderStats& s, int width, int height) {
  fmt::print(
      log, "phasecast-render: {} frames at {}x{}: {:.1f} frames/s render-only, {:.1f} frames/s end-to-end\n",
      s.frames, width, height, s.render_fps(), s.end_to_end_fps());
}

// A line every two seconds on long runs: frames done (of how many) and the rate.
void report_progress(std::ostream& log, const RenderStats& s, std::uint64_t frame, std::uint64_t total) {
  static thread_local double next_report = 2;
  if (s.frames == 1) next_report = 2;
  if (s.wall_seconds < next_report) return;
  next_report = s.wall_seconds + 2;
  fmt::print(log, "phasecast-render: frame {}: {} rendered{} ({:.1f} frames/s)\n", frame, s.frames,
             total ? fmt::format(" of {}", total) : std::string(), s.end_to_end_fps());
  log.flush();
}

void run_local(const RenderOptions& o, const ShLight& light, std::ostream& log) {
  const core::ScenePackage package = core::read_package(*o.package);
  const ClientBasis basis = basis_from_package(package, core::file_content_hash(*o.package));
  std::vector<FrameState> frames;
  if (o.replay) {
    const Recording rec = core::read_recording_file(*o.replay);
    if (rec.truncated)
      fmt::print(log, "phasecast-render: {}: last record truncated, ignored\n", o.replay->string());
    expect_recorded_with(rec, basis, o.replay->string(), o.package->string());
    frames = recorded_frames(rec, o.instance, o.replay->string(), basis.scene).frames;
  } else {
    frames = portrait_frames(package, o.play_irf.value_or(0));
  }
  if (o.max_frames > 0 && frames.size() > o.max_frames) frames.resize(o.max_frames);
  const std::string source = o.replay ? "recording " + o.replay->string() : o.package->string();
  for (const auto& f : frames) validate_frame(f, basis, source);
  if (o.dump_frame && std::none_of(frames.begin(), frames.end(),
                                   [&](const FrameState& f) { return f.frame == *o.dump_frame; })) {
    throw std::invalid_argument(fmt::format("--dump-vertices {}: no such frame (expected {}..{})",
                                            *o.dump_frame, frames.front().frame, frames.back().frame));
  }

  RenderTarget target(basis, o, light, 1.0 / package.attributes.dt);
  fmt::print(log, "phasecast-render: {} ({}), scene '{}', {} points, r_u = {}, r_a = {}, {} frames\n",
             target.renderer->gl_description(), o.backend, basis.scene, basis.points, basis.rank_u,
             basis.rank_a, frames.size());
  for (const auto& f : frames) {
    if (g_interrupted || !target.backend->open()) break;
    target.output->render(f);
    report_progress(log, target.output->stats(), f.frame, frames.size());
  }
  target.output->finish();
  report(log, target.output->stats(), o.width, o.height);
}

// ---- network mode ----------------------------------------------------------------

struct Subscription {
  v1::SceneInfo scene;
  std::uint32_t instance = 0;
  std::string pub_endpoint;
};

// Which instance to follow: --instance, a new one of --create, or the first
// instance of the first scene.
Subscription resolve(CommandClient& cmd, const RenderOptions& o, std::optional<std::uint32_t> created) {
  const auto scenes = cmd.list_scenes();
  Subscription sub;
  sub.pub_endpoint = resolve_pub_endpoint(scenes.pub_endpoint(), cmd.endpoint());
  auto find_scene = [&](const std::string& name) -> const v1::SceneInfo* {
    for (const auto& s : scenes.scenes()) {
      if (s.name() == name) return &s;
    }
    return nullptr;
  };
  std::string scene_name;
  const auto instances = cmd.list_instances();
  const std::optional<std::uint32_t> wanted = o.instance ? o.instance : created;
  if (wanted) {
    const auto it = std::find_if(instances.instances().begin(), instances.instances().end(),
                                 [&](const v1::InstanceInfo& i) { return i.instance() == *wanted; });
    const bool recreate = it == instances.instances().end() && !o.create.empty();
    if (it == instances.instances().end() && !recreate) {
      throw NetworkError(fmt::format("--instance {}: the server at {} has no such instance (it has {})",
                                     *wanted, cmd.endpoint(), instances.instances_size()));
    }
    if (recreate) {  // the server restarted and lost the instance this client created
      const auto info = cmd.create_instance(o.create);
      sub.instance = info.instance();
      scene_name = info.scene();
    } else {
      sub.instance = it->instance();
      scene_name = it->scene();
    }
  } else if (!o.create.empty()) {
    const auto info = cmd.create_instance(o.create);
    sub.instance = info.instance();
    scene_name = info.scene();
  } else {
    if (scenes.scenes().empty())
      throw NetworkError(fmt::format("the server at {} has no scenes", cmd.endpoint()));
    scene_name = scenes.scenes(0).name();
    const auto it = std::find_if(instances.instances().begin(), instances.instances().end(),
                                 [&](const v1::InstanceInfo& i) { return i.scene() == scene_name; });
    if (it == instances.instances().end()) {
      throw NetworkError(fmt::format("the server at {} has no instance of scene '{}' (use --create {})",
                                     cmd.endpoint(), scene_name, scene_name));
    }
    sub.instance = it->instance();
  }
  const auto* scene = find_scene(scene_name);
  if (!scene) {
    throw NetworkError(fmt::format("instance {} plays scene '{}', which list_scenes does not list",
                                   sub.instance, scene_name));
  }
  sub.scene = *scene;
  return sub;
}

// Once the bases are on the GPU the client keeps only their sizes, name and
// hash (what validate_frame and the reconnect check need).
void keep_sizes_only(ClientBasis& basis) {
  basis.U_u = {};
  basis.U_a = {};
  basis.mean_transfer = {};
  basis.mean_shape = {};
  basis.normals = {};
}

ClientBasis download(CommandClient& cmd, const v1::SceneInfo& scene, std::ostream& log) {
  fmt::print(log, "phasecast-render: downloading the bases of '{}' (hash {:016x})\n", scene.name(),
             scene.content_hash());
  std::uint64_t total = 0;
  for (const auto& p : scene.parts()) total += p.total_bytes();
  std::uint64_t finished_parts = 0;
  auto progress = [&](const std::string& part, std::uint64_t done, std::uint64_t size) {
    if (done == size) {
      finished_parts += size;
      fmt::print(log, "phasecast-render:   {} {} bytes ({:.0f}% of {} bytes)\n", part, size,
                 100.0 * double(finished_parts) / double(std::max<std::uint64_t>(total, 1)), total);
    }
  };
  return cmd.download_basis(scene, 1u << 20, progress);
}

void run_network(const RenderOptions& o, const ShLight& light, std::ostream& log) {
  using namespace std::chrono;
  const auto request_timeout = duration_cast<milliseconds>(duration<double>(o.request_timeout_s));
  auto cmd = std::make_unique<CommandClient>(o.connect, request_timeout, 3);
  std::optional<std::uint32_t> created;
  Subscription sub = resolve(*cmd, o, created);
  if (!o.create.empty()) created = sub.instance;
  ClientBasis basis = download(*cmd, sub.scene, log);
  auto target = std::make_unique<RenderTarget>(basis, o, light, 1.0 / sub.scene.dt());
  keep_sizes_only(basis);
  fmt::print(log, "phasecast-render: {} ({}), following instance {} of '{}' on {}\n",
             target->renderer->gl_description(), o.backend, sub.instance, basis.scene, sub.pub_endpoint);
  auto subscriber = std::make_unique<FrameSubscriber>(sub.pub_endpoint, sub.instance);
  SequenceTracker sequence;
  RenderStats done;  // stats of renderers replaced after a basis change
  std::uint64_t reconnects = 0, rendered = 0, rejected = 0;
  const auto frame_timeout = duration_cast<milliseconds>(duration<double>(o.frame_timeout_s));
  while (!g_interrupted && target->backend->open() && (o.max_frames == 0 || rendered < o.max_frames)) {
    if (auto frame = subscriber->receive(frame_timeout)) {
      sequence.observe(frame->seq());
      const FrameState state = frame_state(*frame);
      try {
        validate_frame(state, basis, fmt::format("instance {}", sub.instance));
      } catch (const std::invalid_argument& e) {
        // One bad frame must not end the session: report it, keep the last good one.
        ++rejected;
        fmt::print(log, "phasecast-render: skipped {}\n", e.what());
        continue;
      }
      target->output->render(state);
      report_progress(log, target->output->stats(), state.frame, o.max_frames);
      ++rendered;
      continue;
    }
    // Silence: keep the last frame on screen/disk and reconnect with backoff.
    fmt::print(log, "phasecast-render: no frames for {:.1f} s; reconnecting to {}\n", o.frame_timeout_s,
               o.connect);
    const auto give_up =
        steady_clock::now() + duration_cast<steady_clock::duration>(duration<double>(o.give_up_after_s));
    auto backoff = milliseconds(250);
    for (;;) {
      if (g_interrupted) break;
      try {
        cmd = std::make_unique<CommandClient>(o.connect, request_timeout, 1);
        sub = resolve(*cmd, o, created);
        if (!o.create.empty()) created = sub.instance;
        break;
      } catch (const NetworkError& e) {
        if (steady_clock::now() + backoff > give_up) {
          throw NetworkError(fmt::format("server at {} gone for more than {:.0f} s: {}", o.connect,
                                         o.give_up_after_s, e.what()));
        }
        std::this_thread::sleep_for(backoff);
        backoff = std::min(backoff * 2, milliseconds(4000));
      }
    }
    if (g_interrupted) break;
    ++reconnects;
    if (sub.scene.content_hash() != basis.content_hash || sub.scene.name() != basis.scene) {
      fmt::print(log, "phasecast-render: bases changed (hash {:016x} -> {:016x}); downloading again\n",
                 basis.content_hash, sub.scene.content_hash());
      basis = download(*cmd, sub.scene, log);
      target->output->finish();
      const auto& s = target->output->stats();
      done.frames += s.frames;
      done.render_seconds += s.render_seconds;
      done.wall_seconds += s.wall_seconds;
      target.reset();
      target = std::make_unique<RenderTarget>(basis, o, light, 1.0 / sub.scene.dt());
      keep_sizes_only(basis);
    } else {
      fmt::print(log, "phasecast-render: reconnected; bases unchanged (hash {:016x})\n", basis.content_hash);
    }
    subscriber = std::make_unique<FrameSubscriber>(sub.pub_endpoint, sub.instance);
    sequence.last.reset();  // a new subscription: numbering may start anywhere
  }
  target->output->finish();
  RenderStats total = target->output->stats();
  total.frames += done.frames;
  total.render_seconds += done.render_seconds;
  total.wall_seconds += done.wall_seconds;
  report(log, total, o.width, o.height);
  fmt::print(log,
             "phasecast-render: sequence gaps {} ({} frames missed), stream restarts {}, reconnects {}, "
             "malformed messages {}, rejected frames {}\n",
             sequence.gaps, sequence.missed, sequence.restarts, reconnects, subscriber->malformed(),
             rejected);
}

}  // namespace

void run_render(const RenderOptions& o, std::ostream& log) {
  check_source(o);
  const ShLight light = light_probe(o.light);
  g_interrupted = false;
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
  if (!o.connect.empty()) {
    run_network(o, light, log);
  } else {
    run_local(o, light, log);
  }
}

}  // namespace phasecast::client
