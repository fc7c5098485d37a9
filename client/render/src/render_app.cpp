// phasecast-render's session: one frame source (a server, a recording or the
// package's own portrait) drawn by one render target.

#include "phasecast/client/render_app.h"

#include "network_session.h"
#include "phasecast/client/frame_sources.h"
#include "phasecast/client/image_io.h"
#include "phasecast/core/hash.h"
#include "render_target.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <ostream>
#include <sstream>
#include <thread>
#include <utility>

namespace phasecast::client {
namespace {

// What the GPU holds: ", 312 bytes per point on the GPU (16-bit bases, point
// rows, read as buffer textures), bases bound in 3 blocks of points" (the
// reads only for the compute pass, the blocks only when they exceed one
// storage block).
std::string gpu_note(const LowRankRenderer& renderer, bool half) {
  const int n = renderer.point_blocks();
  const char* layout = basis_layout_name(renderer.basis_layout());
  const std::string reads = renderer.evaluation() == Evaluation::compute_pass
                                ? fmt::format(", read as {}", compute_reads_name(renderer.compute_reads()))
                                : "";
  return fmt::format(
      ", {} bytes per point on the GPU ({}{}{}){}", renderer.gpu_bytes_per_point(),
      half ? "16-bit bases, " : "", layout, reads,
      n > 1 ? fmt::format(", bases bound in {} blocks of points (larger than one storage block)", n) : "");
}

// Per frame number that every instance has, one frame of each, in the
// first instance's order (instances made at different ticks, or with gaps,
// stay in step).
std::vector<std::vector<FrameState>> side_by_side(const std::vector<std::vector<FrameState>>& per_instance) {
  std::vector<std::map<std::uint64_t, const FrameState*>> by_frame(per_instance.size());
  for (std::size_t i = 0; i < per_instance.size(); ++i) {
    for (const auto& f : per_instance[i]) by_frame[i].emplace(f.frame, &f);
  }
  std::vector<std::vector<FrameState>> views;
  for (const auto& f : per_instance.front()) {
    std::vector<FrameState> view;
    for (const auto& frames : by_frame) {
      const auto it = frames.find(f.frame);
      if (it == frames.end()) break;
      view.push_back(*it->second);
    }
    if (view.size() == per_instance.size()) views.push_back(std::move(view));
  }
  return views;
}

// --exposure and --light, before anything is read or drawn.
void check_view_options(const RenderOptions& o) {
  if (o.exposure && (!(*o.exposure > 0) || !std::isfinite(*o.exposure))) {
    throw std::invalid_argument(
        fmt::format("--exposure {} is invalid (expected a positive number)", *o.exposure));
  }
  if (!o.light.empty()) light_probe(o.light);
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
  const bool several = !o.instances.empty() || o.all_instances;
  if (several && (o.instance || !o.create.empty())) {
    throw std::invalid_argument("give --instances, --instance or --create, one of them");
  }
  if (several && o.connect.empty() && !o.replay) {
    throw std::invalid_argument("--instances needs --connect tcp://host:5555 or --replay stream.rec");
  }
  if (o.all_instances && o.connect.empty()) {
    throw std::invalid_argument("--instances all needs --connect (with --replay, list the instances)");
  }
  if (!(o.count >= 1 && o.count <= kMaxInstancesInView)) {
    throw std::invalid_argument(
        fmt::format("--count {} is invalid (expected 1..{} instances)", o.count, kMaxInstancesInView));
  }
  if (o.count > 1 && o.create.empty() && (o.replay || !o.connect.empty())) {
    throw std::invalid_argument("--count needs --create SCENE (network) or local mode (--package p.h5)");
  }
  if (o.instances.size() > static_cast<std::size_t>(kMaxInstancesInView)) {
    throw std::invalid_argument(fmt::format("--instances lists {} instances (expected at most {})",
                                            o.instances.size(), kMaxInstancesInView));
  }
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
  check_view_options(o);
}

// Replay of several instances: their frames side by side, tick by tick, as
// long as every one of them has a frame.
std::vector<std::vector<FrameState>> recorded_views(const Recording& rec, const RenderOptions& o,
                                                    const ClientBasis& basis) {
  std::vector<std::vector<FrameState>> per_instance;
  if (o.instances.empty()) {
    per_instance.push_back(recorded_frames(rec, o.instance, o.replay->string(), basis.scene).frames);
  } else {
    for (const auto id : o.instances)
      per_instance.push_back(recorded_frames(rec, id, o.replay->string(), basis.scene).frames);
  }
  return side_by_side(per_instance);
}

// Local mode: the IRF played by `count` copies, each further on in it.
std::vector<std::vector<FrameState>> portrait_views(const core::ScenePackage& package,
                                                    const RenderOptions& o) {
  const auto frames = portrait_frames(package, o.play_irf.value_or(0));
  std::vector<std::vector<FrameState>> per_instance(static_cast<std::size_t>(o.count));
  const std::size_t n = frames.size(), stagger = std::max<std::size_t>(1, n / per_instance.size());
  for (std::size_t i = 0; i < per_instance.size(); ++i) {
    for (std::size_t t = 0; t < n; ++t) {
      FrameState f = frames[(t + i * stagger) % n];
      f.frame = frames[t].frame;
      per_instance[i].push_back(std::move(f));
    }
  }
  return side_by_side(per_instance);
}

void finish_output(RenderTarget& target, std::ostream& log, const RenderOptions& o) {
  target.output->finish();
  report(log, target.output->stats(), o.width, o.height);
}

void run_local(const RenderOptions& o, std::ostream& log, const std::atomic<bool>& interrupted) {
  const core::ScenePackage package = core::read_package(*o.package);
  const ClientBasis basis = basis_from_package(package, core::file_content_hash(*o.package));
  std::vector<std::vector<FrameState>> views;  // per tick, one frame per instance
  if (o.replay) {
    const Recording rec = core::read_recording_file(*o.replay);
    if (rec.truncated)
      fmt::print(log, "phasecast-render: {}: last record truncated, ignored\n", o.replay->string());
    expect_recorded_with(rec, basis, o.replay->string(), o.package->string());
    views = recorded_views(rec, o, basis);
  } else {
    views = portrait_views(package, o);
  }
  if (o.max_frames > 0 && views.size() > o.max_frames) views.resize(o.max_frames);
  const std::string source = o.replay ? "recording " + o.replay->string() : o.package->string();
  for (const auto& view : views) {
    for (const auto& f : view) validate_frame(f, basis, source);
  }
  if (o.dump_frame && std::none_of(views.begin(), views.end(), [&](const std::vector<FrameState>& v) {
        return v.front().frame == *o.dump_frame;
      })) {
    throw std::invalid_argument(fmt::format("--dump-vertices {}: no such frame (expected {}..{})",
                                            *o.dump_frame, views.front().front().frame,
                                            views.back().front().frame));
  }
  const int instances = views.empty() ? 1 : static_cast<int>(views.front().size());
  RenderTarget target(basis, o, 1.0 / package.attributes.dt, instances);
  fmt::print(log, "phasecast-render: {} ({}), scene '{}', {} points, r_u = {}, r_a = {}, {} frames{}{}\n",
             target.renderer->gl_description(), o.backend, basis.scene, basis.points, basis.rank_u,
             basis.rank_a, views.size(), instances > 1 ? fmt::format(", {} instances", instances) : "",
             gpu_note(*target.renderer, o.half));
  // On a screen the frames play at the scene's rate; files take them as fast as they come.
  FramePacer pacer(package.attributes.dt);
  for (const auto& view : views) {
    if (interrupted || !target.backend->open()) break;
    if (target.backend->shows_frames()) std::this_thread::sleep_for(pacer.wait(FramePacer::Clock::now()));
    target.output->render(view);
    report_progress(log, target.output->stats(), view.front().frame, views.size());
  }
  finish_output(target, log, o);
}

}  // namespace

std::vector<std::uint32_t> parse_instance_list(const std::string& text) {
  std::vector<std::uint32_t> ids;
  std::istringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    std::size_t used = 0;
    unsigned long id = 0;
    try {
      id = std::stoul(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || item[0] == '-' || id > UINT32_MAX ||
        std::find(ids.begin(), ids.end(), id) != ids.end()) {
      throw std::invalid_argument(
          fmt::format("--instances '{}' is invalid at '{}' (expected all, or instance ids each once: 1,2,3)",
                      text, item));
    }
    ids.push_back(static_cast<std::uint32_t>(id));
  }
  if (ids.empty() || text.back() == ',')
    throw std::invalid_argument(fmt::format("--instances '{}' is invalid (expected all, or 1,2,3)", text));
  return ids;
}

bool parse_on_off(const std::string& value, const std::string& option) {
  if (value == "on") return true;
  if (value == "off") return false;
  throw std::invalid_argument(fmt::format("{} '{}' is invalid (expected on or off)", option, value));
}

namespace {

// A source of chunks is the only frame source; the others' options would be ignored.
void check_chunk_options(const RenderOptions& o, const FrameChunks& chunks) {
  const std::pair<bool, const char*> others[] = {{!o.connect.empty(), "--connect"},
                                                 {o.replay.has_value(), "--replay"},
                                                 {o.package.has_value(), "--package"},
                                                 {o.instance.has_value(), "--instance"},
                                                 {!o.instances.empty() || o.all_instances, "--instances"},
                                                 {!o.create.empty(), "--create"},
                                                 {o.count != 1, "--count"},
                                                 {o.layout.has_value(), "--layout"},
                                                 {o.play_irf.has_value(), "--play-irf"},
                                                 {!o.server_key.empty(), "--server-key"},
                                                 {!o.client_key.empty(), "--client-key"}};
  for (const auto& [given, name] : others) {
    if (given) {
      throw std::invalid_argument(fmt::format(
          "{} is not for {} (expected it alone as the frame source, with output and view options)", name,
          chunks.source));
    }
  }
  check_view_options(o);
  if (o.dump_frame && *o.dump_frame >= chunks.frames) {
    throw std::invalid_argument(
        fmt::format("--dump-vertices {}: no such frame (expected 0..{})", *o.dump_frame, chunks.frames - 1));
  }
}

}  // namespace

void render_chunks(const RenderOptions& o, const FrameChunks& chunks, std::ostream& log,
                   const std::atomic<bool>& interrupted) {
  check_chunk_options(o, chunks);
  std::unique_ptr<RenderTarget> target;
  FramePacer pacer(chunks.dt);
  for (int c = 0; c < chunks.chunks && !interrupted; ++c) {
    const FrameChunk chunk = chunks.chunk(c);
    chunk.basis.validate(chunks.source);
    if (!target) {
      target = std::make_unique<RenderTarget>(chunk.basis, o, 1.0 / chunks.dt);
      fmt::print(log, "phasecast-render: {} ({}), {}, {} points, {} frames{}\n",
                 target->renderer->gl_description(), o.backend, chunks.description, chunk.basis.points,
                 chunks.frames, gpu_note(*target->renderer, o.half));
    } else {
      target->replace_bases(chunk.basis, o);
    }
    for (const auto& frame : chunk.frames) {
      if (interrupted || !target->backend->open()) return finish_output(*target, log, o);
      if (target->backend->shows_frames()) std::this_thread::sleep_for(pacer.wait(FramePacer::Clock::now()));
      target->output->render(std::vector<FrameState>{frame});
      report_progress(log, target->output->stats(), frame.frame, chunks.frames);
    }
  }
  if (target) finish_output(*target, log, o);
}

void run_render(const RenderOptions& o, std::ostream& log, const std::atomic<bool>& interrupted) {
  check_source(o);
  if (o.connect.empty()) {
    run_local(o, log, interrupted);
    return;
  }
  NetworkSession session(o, log, interrupted);
  session.run();
  session.finish();
}

}  // namespace phasecast::client
