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
#include <ostream>
#include <utility>

namespace phasecast::client {
namespace {

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

void run_local(const RenderOptions& o, const ShLight& light, std::ostream& log,
               const std::atomic<bool>& interrupted) {
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
    if (interrupted || !target.backend->open()) break;
    target.output->render(f);
    report_progress(log, target.output->stats(), f.frame, frames.size());
  }
  target.output->finish();
  report(log, target.output->stats(), o.width, o.height);
}

}  // namespace

bool parse_on_off(const std::string& value, const std::string& option) {
  if (value == "on") return true;
  if (value == "off") return false;
  throw std::invalid_argument(fmt::format("{} '{}' is invalid (expected on or off)", option, value));
}

void run_render(const RenderOptions& o, std::ostream& log, const std::atomic<bool>& interrupted) {
  check_source(o);
  const ShLight light = light_probe(o.light);
  if (o.connect.empty()) {
    run_local(o, light, log, interrupted);
    return;
  }
  NetworkSession session(o, light, log, interrupted);
  session.run();
  session.finish();
}

}  // namespace phasecast::client
