#include "phasecast/client/render_app.h"

#include "phasecast/client/frame_output.h"
#include "phasecast/client/frame_sources.h"
#include "phasecast/client/image_io.h"
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
#include <utility>

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
  if ((!o.server_key.empty() || !o.client_key.empty()) && o.connect.empty()) {
    throw std::invalid_argument(
        fmt::format("{} needs --connect tcp://host:5555 (CURVE secures the connection)",
                    o.server_key.empty() ? "--client-key" : "--server-key"));
  }
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

// Backend, renderer and outputs. The renderer holds one set of bases; the
// backend and the outputs last the whole run.
struct RenderTarget {
  std::unique_ptr<RenderBackend> backend;
  std::unique_ptr<LowRankRenderer> renderer;
  std::unique_ptr<FrameOutput> output;

  // `frame_rate`: frames per second of the stream (1 / dt), for the video.
  RenderTarget(const ClientBasis& basis, const RenderOptions& o, const ShLight& light, double frame_rate) {
    backend = make_render_backend(o.backend, o.width, o.height);
    make_renderer(basis, o, light);
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
  void replace_bases(const ClientBasis& basis, const RenderOptions& o, const ShLight& light) {
    renderer.reset();  // frees the old bases' GPU buffers first
    make_renderer(basis, o, light);
    output->set_renderer(*renderer);
  }

 private:
  void make_renderer(const ClientBasis& basis, const RenderOptions& o, const ShLight& light) {
    renderer = std::make_unique<LowRankRenderer>(*backend, basis, o.width, o.height);
    renderer->set_light(light);
    renderer->set_camera(camera_for(basis, o));
    renderer->set_exposure(o.exposure);
    renderer->set_backdrop(o.backdrop ? Backdrop::ground : Backdrop::none);
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

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

std::chrono::milliseconds milliseconds_of(double seconds) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::duration<double>(seconds));
}

// Follows one instance of a server, also across restarts of the server
// (docs/client.md, "Network mode"). Frames are drawn while they match the
// bases the client holds; when the connection comes back after a loss, when
// the sequence starts again or when a frame is rejected, it asks the server
// again and downloads the bases before drawing on if their hash changed.
// Each such event is one line, never one per frame. --give-up-after bounds
// the time without a rendered frame, whatever the reason.
class NetworkSession {
 public:
  NetworkSession(const RenderOptions& o, const ShLight& light, std::ostream& log)
      : o_(o),
        light_(light),
        log_(log),
        curve_(load_curve_client_keys(o.server_key, o.client_key)),
        request_timeout_(milliseconds_of(o.request_timeout_s)),
        frame_timeout_(milliseconds_of(o.frame_timeout_s)) {
    cmd_ = std::make_unique<CommandClient>(o.connect, request_timeout_, 3, curve_);
    sub_ = resolve(*cmd_, o, created_);
    if (!o.create.empty()) created_ = sub_.instance;
    basis_ = download(*cmd_, sub_.scene, log);
    target_ = std::make_unique<RenderTarget>(basis_, o, light, 1.0 / sub_.scene.dt());
    keep_sizes_only(basis_);
    fmt::print(log, "phasecast-render: {} ({}), following instance {} of '{}' on {}{}\n",
               target_->renderer->gl_description(), o.backend, sub_.instance, basis_.scene, sub_.pub_endpoint,
               curve_.enabled() ? " (CURVE)" : "");
    subscribe();
    last_rendered_ = std::chrono::steady_clock::now();
  }

  void run() {
    while (keep_going()) {
      check_give_up();
      const auto left = milliseconds_of(o_.give_up_after_s - seconds_since(last_rendered_));
      auto frame =
          subscriber_->receive(std::max(std::chrono::milliseconds(1), std::min(left, frame_timeout_)));
      if (subscriber_->take_reconnected()) {
        ++reconnects_;
        const bool resubscribed = recheck(
            fmt::format("the frame connection to {} was lost and made again", sub_.pub_endpoint), true);
        if (resubscribed) continue;  // `frame` came through the old subscription
        restart_explained_ = true;   // the new server's first frame steps back: already checked
      }
      if (frame) {
        handle(*frame);
      } else if (seconds_since(last_received_) >= o_.frame_timeout_s) {
        reconnect(fmt::format("no frames for {:.1f} s", o_.frame_timeout_s));
      }
    }
  }

  void finish() {
    target_->output->finish();
    report(log_, target_->output->stats(), o_.width, o_.height);
    fmt::print(log_,
               "phasecast-render: sequence gaps {} ({} frames missed), stream restarts {}, reconnects {}, "
               "malformed messages {}, rejected frames {}\n",
               sequence_.gaps, sequence_.missed, sequence_.restarts, reconnects_,
               malformed_ + subscriber_->malformed(), rejected_);
  }

 private:
  bool keep_going() const {
    return !g_interrupted && target_->backend->open() && (o_.max_frames == 0 || rendered_ < o_.max_frames);
  }

  void handle(const v1::Frame& frame) {
    last_received_ = std::chrono::steady_clock::now();
    if (sequence_.observe(frame.seq()) && !std::exchange(restart_explained_, false)) {
      // A restarted server, maybe with another package: ask before drawing.
      const auto why =
          fmt::format("instance {}: the stream started again (seq {})", sub_.instance, frame.seq());
      if (recheck(why, true)) return;
    }
    const FrameState state = frame_state(frame);
    try {
      check_frame(frame, state);
    } catch (const std::invalid_argument& e) {
      reject(e.what());
      return;
    }
    if (rejected_run_ > 1)
      fmt::print(log_, "phasecast-render: rendering again after {} rejected frames\n", rejected_run_);
    rejected_run_ = 0;
    render(state);
  }

  // The frame must fit the bases held (one bad frame never ends the session).
  void check_frame(const v1::Frame& frame, const FrameState& state) const {
    const std::string source = fmt::format("instance {}", sub_.instance);
    if (!frame.scene().empty() && frame.scene() != basis_.scene) {
      throw std::invalid_argument(
          fmt::format("{}: frame {}: scene '{}' (expected '{}', whose bases this client holds)", source,
                      state.frame, frame.scene(), basis_.scene));
    }
    validate_frame(state, basis_, source);
  }

  void render(const FrameState& state) {
    const unsigned session = target_->output->session();
    target_->output->render(state);
    if (target_->output->session() != session && o_.out_dir) {
      fmt::print(log_, "phasecast-render: frame numbers started again at {}; PNGs from now on: {}\n",
                 state.frame, frame_file_name(state.frame, target_->output->session()));
    }
    report_progress(log_, target_->output->stats(), state.frame, o_.max_frames);
    ++rendered_;
    last_rendered_ = std::chrono::steady_clock::now();
    stalled_.clear();
  }

  // The first rejected frame of a run is printed and makes the client ask the
  // server again (another package?); the rest of the run is only counted, and
  // asks again at most once per --frame-timeout.
  void reject(const std::string& why) {
    ++rejected_;
    ++rejected_run_;
    stalled_ = fmt::format("every frame was rejected (last: {})", why);
    if (rejected_run_ == 1) fmt::print(log_, "phasecast-render: skipped {}\n", why);
    if (rejected_run_ == 1 || seconds_since(last_recheck_) >= o_.frame_timeout_s) recheck(why, false);
  }

  // Asks the server which instance and bases to follow; downloads the bases
  // when their hash changed. `announce`: say why and what came out, even when
  // nothing changed. Returns whether the subscription was replaced.
  bool recheck(const std::string& why, bool announce) {
    last_recheck_ = std::chrono::steady_clock::now();
    if (announce) fmt::print(log_, "phasecast-render: {}; checking the server's bases\n", why);
    try {
      return adopt(resolve(*cmd_, o_, created_), false, announce);
    } catch (const NetworkError& e) {
      reconnect(e.what());  // gone again, or the instance is not there (yet)
      return true;
    }
  }

  // The server is gone: new connections until one answers, or until
  // --give-up-after has passed without a rendered frame.
  void reconnect(const std::string& why) {
    fmt::print(log_, "phasecast-render: {}; reconnecting to {}\n", why, o_.connect);
    log_.flush();
    auto backoff = std::chrono::milliseconds(250);
    while (!g_interrupted) {
      check_give_up();
      try {
        // One try per attempt while the server is gone; once it answers, the
        // download and later requests get the usual three.
        cmd_ = std::make_unique<CommandClient>(o_.connect, request_timeout_, 1, curve_);
        const Subscription next = resolve(*cmd_, o_, created_);
        cmd_->set_attempts(3);
        ++reconnects_;
        adopt(next, true, true);
        return;
      } catch (const NoReplyError& e) {
        // The request waited for the server, which answers it as soon as it is
        // back: try again at once.
        stalled_ = fmt::format("server at {} gone: {}", o_.connect, e.what());
        continue;
      } catch (const NetworkError& e) {
        stalled_ = fmt::format("server at {}: {}", o_.connect, e.what());
      }
      // The server answered but refused (an instance not there yet?): pause.
      const auto left = milliseconds_of(o_.give_up_after_s - seconds_since(last_rendered_));
      std::this_thread::sleep_for(std::clamp(left, std::chrono::milliseconds(0), backoff));
      backoff = std::min(backoff * 2, std::chrono::milliseconds(1000));
    }
  }

  // Takes `next` as the subscription, with new bases if their hash changed.
  bool adopt(const Subscription& next, bool resubscribe, bool announce) {
    const bool changed =
        next.scene.content_hash() != basis_.content_hash || next.scene.name() != basis_.scene;
    if (changed) {
      fmt::print(log_, "phasecast-render: bases changed (hash {:016x} -> {:016x}); downloading again\n",
                 basis_.content_hash, next.scene.content_hash());
      ClientBasis fresh = download(*cmd_, next.scene, log_);
      target_->replace_bases(fresh, o_, light_);
      keep_sizes_only(fresh);
      basis_ = std::move(fresh);
    } else if (announce) {
      fmt::print(log_, "phasecast-render: reconnected; bases unchanged (hash {:016x})\n",
                 basis_.content_hash);
    }
    log_.flush();
    resubscribe =
        resubscribe || changed || next.instance != sub_.instance || next.pub_endpoint != sub_.pub_endpoint;
    sub_ = next;
    if (!o_.create.empty()) created_ = sub_.instance;
    if (resubscribe) subscribe();
    return resubscribe;
  }

  void subscribe() {
    if (subscriber_) malformed_ += subscriber_->malformed();
    subscriber_ = std::make_unique<FrameSubscriber>(sub_.pub_endpoint, sub_.instance, curve_);
    sequence_.last.reset();  // a new subscription: numbering may start anywhere
    restart_explained_ = false;
    last_received_ = std::chrono::steady_clock::now();
  }

  void check_give_up() {
    if (seconds_since(last_rendered_) <= o_.give_up_after_s) return;
    std::string why = stalled_;
    if (why.empty()) {
      const std::string problem = subscriber_->connection_problem();
      why = fmt::format("no frames of instance {} came from {}{}", sub_.instance, sub_.pub_endpoint,
                        problem.empty() ? "" : ": " + problem);
    }
    throw NetworkError(
        fmt::format("no frame rendered for {:.0f} s (--give-up-after): {}", o_.give_up_after_s, why));
  }

  const RenderOptions& o_;
  const ShLight& light_;
  std::ostream& log_;
  const CurveClientKeys curve_;
  const std::chrono::milliseconds request_timeout_, frame_timeout_;
  std::unique_ptr<CommandClient> cmd_;
  std::optional<std::uint32_t> created_;  // --create: the instance made, made again after a restart
  Subscription sub_;
  ClientBasis basis_;  // sizes, scene and hash only, once on the GPU
  std::unique_ptr<RenderTarget> target_;
  std::unique_ptr<FrameSubscriber> subscriber_;
  SequenceTracker sequence_;
  std::uint64_t reconnects_ = 0, rendered_ = 0, rejected_ = 0, rejected_run_ = 0, malformed_ = 0;
  bool restart_explained_ = false;  // a reconnect was checked; the step back of seq it brings needs no check
  std::chrono::steady_clock::time_point last_rendered_, last_received_, last_recheck_;
  std::string stalled_;  // why nothing is rendered, for the give-up message; "" while frames are drawn
};

void run_network(const RenderOptions& o, const ShLight& light, std::ostream& log) {
  NetworkSession session(o, light, log);
  session.run();
  session.finish();
}

}  // namespace

bool parse_on_off(const std::string& value, const std::string& option) {
  if (value == "on") return true;
  if (value == "off") return false;
  throw std::invalid_argument(fmt::format("{} '{}' is invalid (expected on or off)", option, value));
}

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
