#include "network_session.h"

#include "phasecast/client/frame_sources.h"
#include "phasecast/client/image_io.h"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <map>
#include <ostream>
#include <thread>
#include <utility>

namespace phasecast::client {
namespace {

// Instance -> the scene it plays, as the server lists them.
std::map<std::uint32_t, std::string> scenes_of_instances(CommandClient& cmd) {
  const v1::InstanceList listed = cmd.list_instances();
  std::map<std::uint32_t, std::string> scene_of;
  for (const auto& i : listed.instances()) scene_of[i.instance()] = i.scene();
  return scene_of;
}

// The instances the options name, made if they ask for new ones (--create,
// --count of them; made again when a restarted server lost them).
std::vector<std::uint32_t> wanted_instances(CommandClient& cmd, const RenderOptions& o,
                                            const std::vector<std::uint32_t>& created,
                                            const std::map<std::uint32_t, std::string>& scene_of,
                                            const v1::SceneList& scenes) {
  const auto exists = [&](std::uint32_t id) { return scene_of.count(id) != 0; };
  if (o.instance || !o.instances.empty()) {
    const auto ids = o.instance ? std::vector<std::uint32_t>{*o.instance} : o.instances;
    for (const auto id : ids) {
      if (!exists(id)) {
        throw NetworkError(fmt::format("--instance{} {}: the server at {} has no such instance (it has {})",
                                       o.instance ? "" : "s", id, cmd.endpoint(), scene_of.size()));
      }
    }
    return ids;
  }
  if (!o.create.empty()) {
    if (!created.empty() && std::all_of(created.begin(), created.end(), exists)) return created;
    std::vector<std::uint32_t> made;
    for (int i = 0; i < o.count; ++i) made.push_back(cmd.create_instance(o.create).instance());
    return made;
  }
  if (scenes.scenes().empty())
    throw NetworkError(fmt::format("the server at {} has no scenes", cmd.endpoint()));
  const std::string& first = scenes.scenes(0).name();
  std::vector<std::uint32_t> of_first;
  for (const auto& [id, scene] : scene_of) {
    if (scene == first) of_first.push_back(id);
  }
  if (of_first.empty()) {
    throw NetworkError(fmt::format("the server at {} has no instance of scene '{}' (use --create {})",
                                   cmd.endpoint(), first, first));
  }
  if (!o.all_instances) of_first.resize(1);
  return of_first;
}

// Which instances to follow: --instance or --instances, new ones of
// --create, every instance of the first scene (--instances all), or its
// first instance. One renderer draws one scene's instances.
Subscription resolve(CommandClient& cmd, const RenderOptions& o, const std::vector<std::uint32_t>& created) {
  const auto scenes = cmd.list_scenes();
  Subscription sub;
  sub.pub_endpoint = resolve_pub_endpoint(scenes.pub_endpoint(), cmd.endpoint());
  auto scene_of = scenes_of_instances(cmd);
  sub.instances = wanted_instances(cmd, o, created, scene_of, scenes);
  // Id order: the grid's order, and the order of a scene's batches (the view
  // is drawn when the last one's frame came).
  std::sort(sub.instances.begin(), sub.instances.end());
  if (!scene_of.count(sub.instances.front())) scene_of = scenes_of_instances(cmd);  // made just now
  const std::string scene_name = scene_of[sub.instances.front()];
  for (const auto id : sub.instances) {
    if (scene_of[id] != scene_name) {
      throw NetworkError(fmt::format(
          "--instances: instance {} plays '{}' and instance {} plays '{}' (expected instances of one scene: "
          "one renderer holds one scene's bases)",
          sub.instances.front(), scene_name, id, scene_of[id]));
    }
  }
  const auto it = std::find_if(scenes.scenes().begin(), scenes.scenes().end(),
                               [&](const v1::SceneInfo& s) { return s.name() == scene_name; });
  if (it == scenes.scenes().end()) {
    throw NetworkError(fmt::format("instance {} plays scene '{}', which list_scenes does not list",
                                   sub.instances.front(), scene_name));
  }
  sub.scene = *it;
  return sub;
}

// "instance 3" or "instances 1, 2, 3" (the first eight of a long list).
std::string describe(const std::vector<std::uint32_t>& ids) {
  if (ids.size() == 1) return fmt::format("instance {}", ids.front());
  const std::size_t shown = std::min<std::size_t>(ids.size(), 8);
  return fmt::format("{} instances ({}{})", ids.size(),
                     fmt::join(ids.begin(), ids.begin() + static_cast<std::ptrdiff_t>(shown), ", "),
                     shown < ids.size() ? ", ..." : "");
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

}  // namespace

NetworkSession::NetworkSession(const RenderOptions& o, std::ostream& log,
                               const std::atomic<bool>& interrupted)
    : o_(o),
      log_(log),
      interrupted_(interrupted),
      curve_(load_curve_client_keys(o.server_key, o.client_key)),
      request_timeout_(milliseconds_of(o.request_timeout_s)),
      frame_timeout_(milliseconds_of(o.frame_timeout_s)) {
  cmd_ = std::make_unique<CommandClient>(o.connect, request_timeout_, 3, curve_);
  sub_ = resolve(*cmd_, o, created_);
  if (!o.create.empty()) created_ = sub_.instances;
  basis_ = download(*cmd_, sub_.scene, log);
  target_ = std::make_unique<RenderTarget>(basis_, o, 1.0 / sub_.scene.dt(),
                                           static_cast<int>(sub_.instances.size()));
  keep_sizes_only(basis_);
  fmt::print(log, "phasecast-render: {} ({}), following {} of '{}' on {}{}\n",
             target_->renderer->gl_description(), o.backend, describe(sub_.instances), basis_.scene,
             sub_.pub_endpoint, curve_.enabled() ? " (CURVE)" : "");
  subscribe();
  last_rendered_ = std::chrono::steady_clock::now();
}

void NetworkSession::run() {
  while (keep_going()) {
    check_give_up();
    const auto left = milliseconds_of(o_.give_up_after_s - seconds_since(last_rendered_));
    auto frames =
        subscriber_->receive_all(std::max(std::chrono::milliseconds(1), std::min(left, frame_timeout_)));
    if (subscriber_->take_reconnected()) {
      ++reconnects_;
      const bool resubscribed =
          recheck(fmt::format("the frame connection to {} was lost and made again", sub_.pub_endpoint), true);
      if (resubscribed) continue;  // `frames` came through the old subscription
      restart_explained_ = true;   // the new server's first frame steps back: already checked
    }
    if (!frames.empty()) {
      handle(frames);
    } else if (seconds_since(last_received_) >= o_.frame_timeout_s) {
      reconnect(fmt::format("no frames for {:.1f} s", o_.frame_timeout_s));
    }
  }
}

void NetworkSession::finish() {
  target_->output->finish();
  report(log_, target_->output->stats(), o_.width, o_.height);
  fmt::print(log_,
             "phasecast-render: sequence gaps {} ({} frames missed), stream restarts {}, reconnects {}, "
             "malformed messages {}, rejected frames {}\n",
             sequence_.gaps, sequence_.missed, sequence_.restarts, reconnects_,
             malformed_ + subscriber_->malformed(), rejected_);
}

bool NetworkSession::keep_going() const {
  return !interrupted_ && target_->backend->open() && (o_.max_frames == 0 || rendered_ < o_.max_frames);
}

// Frames of the followed instances from one message. The view is drawn
// when the last followed instance's frame came: a scene's batches are
// published in id order, so the others of that tick came before it.
void NetworkSession::handle(const std::vector<v1::Frame>& frames) {
  last_received_ = std::chrono::steady_clock::now();
  for (const auto& frame : frames) {
    if (frame.instance() != sub_.instances.front()) continue;
    if (sequence_.observe(frame.seq()) && !std::exchange(restart_explained_, false)) {
      // A restarted server, maybe with another package: ask before drawing.
      const auto why =
          fmt::format("instance {}: the stream started again (seq {})", frame.instance(), frame.seq());
      if (recheck(why, true)) return;
    }
  }
  for (const auto& frame : frames) {
    FrameState state = frame_state(frame);
    try {
      check_frame(frame, state);
    } catch (const std::invalid_argument& e) {
      reject(e.what());
      return;
    }
    latest_[frame.instance()] = std::move(state);
  }
  if (frames.back().instance() != sub_.instances.back() || latest_.size() < sub_.instances.size()) return;
  if (rejected_run_ > 1)  // the run of rejected frames may span a reconnect
    fmt::print(log_, "phasecast-render: rendering again after {} rejected frames\n", rejected_run_);
  rejected_run_ = 0;
  state_ = State::following;
  std::vector<FrameState> view;
  for (const auto id : sub_.instances) view.push_back(latest_.at(id));
  render(view);
}

// The frame must fit the bases held (one bad frame never ends the session).
void NetworkSession::check_frame(const v1::Frame& frame, const FrameState& state) const {
  const std::string source = fmt::format("instance {}", frame.instance());
  if (!frame.scene().empty() && frame.scene() != basis_.scene) {
    throw std::invalid_argument(
        fmt::format("{}: frame {}: scene '{}' (expected '{}', whose bases this client holds)", source,
                    state.frame, frame.scene(), basis_.scene));
  }
  validate_frame(state, basis_, source);
}

void NetworkSession::render(const std::vector<FrameState>& view) {
  const unsigned session = target_->output->session();
  target_->output->render(view);
  const std::uint64_t frame = view.front().frame;
  if (target_->output->session() != session && o_.out_dir) {
    fmt::print(log_, "phasecast-render: frame numbers started again at {}; PNGs from now on: {}\n", frame,
               frame_file_name(frame, target_->output->session()));
  }
  report_progress(log_, target_->output->stats(), frame, o_.max_frames);
  ++rendered_;
  last_rendered_ = std::chrono::steady_clock::now();
  stalled_.clear();
}

// The first rejected frame of a run is printed and makes the client ask the
// server again (another package?); the rest of the run is only counted, and
// asks again at most once per --frame-timeout.
void NetworkSession::reject(const std::string& why) {
  ++rejected_;
  ++rejected_run_;
  state_ = State::rejecting;
  stalled_ = fmt::format("every frame was rejected (last: {})", why);
  if (rejected_run_ == 1) fmt::print(log_, "phasecast-render: skipped {}\n", why);
  if (rejected_run_ == 1 || seconds_since(last_recheck_) >= o_.frame_timeout_s) recheck(why, false);
}

// Asks the server which instance and bases to follow; downloads the bases
// when their hash changed. `announce`: say why and what came out, even when
// nothing changed. Returns whether the subscription was replaced.
bool NetworkSession::recheck(const std::string& why, bool announce) {
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
void NetworkSession::reconnect(const std::string& why) {
  fmt::print(log_, "phasecast-render: {}; reconnecting to {}\n", why, o_.connect);
  log_.flush();
  state_ = State::reconnecting;
  auto backoff = std::chrono::milliseconds(250);
  while (!interrupted_) {
    check_give_up();
    try {
      // One try per attempt while the server is gone; once it answers, the
      // download and later requests get the usual three.
      cmd_ = std::make_unique<CommandClient>(o_.connect, request_timeout_, 1, curve_);
      const Subscription next = resolve(*cmd_, o_, created_);
      cmd_->set_attempts(3);
      ++reconnects_;
      adopt(next, true, true);
      state_ = State::following;
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
bool NetworkSession::adopt(const Subscription& next, bool resubscribe, bool announce) {
  const bool changed = next.scene.content_hash() != basis_.content_hash || next.scene.name() != basis_.scene;
  if (changed) {
    fmt::print(log_, "phasecast-render: bases changed (hash {:016x} -> {:016x}); downloading again\n",
               basis_.content_hash, next.scene.content_hash());
    ClientBasis fresh = download(*cmd_, next.scene, log_);
    target_->replace_bases(fresh, o_);
    keep_sizes_only(fresh);
    basis_ = std::move(fresh);
  } else if (announce) {
    fmt::print(log_, "phasecast-render: reconnected; bases unchanged (hash {:016x})\n", basis_.content_hash);
  }
  log_.flush();
  resubscribe =
      resubscribe || changed || next.instances != sub_.instances || next.pub_endpoint != sub_.pub_endpoint;
  if (next.instances.size() != sub_.instances.size()) {
    fmt::print(log_, "phasecast-render: following {} now\n", describe(next.instances));
    target_->set_instances(static_cast<int>(next.instances.size()), o_);
  }
  sub_ = next;
  if (!o_.create.empty()) created_ = sub_.instances;
  if (resubscribe) subscribe();
  return resubscribe;
}

void NetworkSession::subscribe() {
  if (subscriber_) malformed_ += subscriber_->malformed();
  subscriber_ =
      std::make_unique<FrameSubscriber>(sub_.pub_endpoint, sub_.scene.name(), sub_.instances, curve_);
  sequence_.last.reset();  // a new subscription: numbering may start anywhere
  latest_.clear();
  restart_explained_ = false;
  last_received_ = std::chrono::steady_clock::now();
}

void NetworkSession::check_give_up() {
  if (seconds_since(last_rendered_) <= o_.give_up_after_s) return;
  std::string why = stalled_;
  if (why.empty()) {
    const std::string problem = subscriber_->connection_problem();
    why = fmt::format("no frames of {} came from {}{}", describe(sub_.instances), sub_.pub_endpoint,
                      problem.empty() ? "" : ": " + problem);
  }
  throw NetworkError(
      fmt::format("no frame rendered for {:.0f} s (--give-up-after): {}", o_.give_up_after_s, why));
}

}  // namespace phasecast::client
