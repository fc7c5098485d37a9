#pragma once
// phasecast-render following an instance of a server (docs/client.md,
// "Network mode").

#include "phasecast/client/curve_options.h"
#include "phasecast/client/network.h"
#include "phasecast/client/render_app.h"
#include "phasecast/client/sh_light.h"
#include "render_target.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <iosfwd>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::client {

// The instances followed (in id order, of one scene), their scene and where
// their frames are published.
struct Subscription {
  v1::SceneInfo scene;
  std::vector<std::uint32_t> instances;
  std::string pub_endpoint;
};

// Follows instances of a server (one, or several of one scene drawn in one
// view), also across restarts of the server
// (docs/client.md, "Network mode"). Frames are drawn while they match the
// bases the client holds; when the connection comes back after a loss, when
// the sequence starts again or when a frame is rejected, it asks the server
// again and downloads the bases before drawing on if their hash changed.
// Each such event is one line, never one per frame. --give-up-after bounds
// the time without a rendered frame, whatever the reason.
class NetworkSession {
 public:
  NetworkSession(const RenderOptions& o, std::ostream& log, const std::atomic<bool>& interrupted);
  void run();
  void finish();

  // Where the session stands with its server. Each change of state is one
  // line of the log, never one per frame.
  enum class State {
    following,     // frames arrive and are drawn
    rejecting,     // frames arrive but do not fit the bases held: counted, and the server asked again
    reconnecting,  // the server is gone: new connections until one answers or --give-up-after
  };
  State state() const { return state_; }

 private:
  bool keep_going() const;
  void handle(const std::vector<v1::Frame>& frames);

  // The frame must fit the bases held (one bad frame never ends the session).
  void check_frame(const v1::Frame& frame, const FrameState& state) const;
  void render(const std::vector<FrameState>& view);

  // The first rejected frame of a run is printed and makes the client ask the
  // server again (another package?); the rest of the run is only counted, and
  // asks again at most once per --frame-timeout.
  void reject(const std::string& why);

  // Asks the server which instance and bases to follow; downloads the bases
  // when their hash changed. `announce`: say why and what came out, even when
  // nothing changed. Returns whether the subscription was replaced.
  bool recheck(const std::string& why, bool announce);

  // The server is gone: new connections until one answers, or until
  // --give-up-after has passed without a rendered frame.
  void reconnect(const std::string& why);

  // Takes `next` as the subscription, with new bases if their hash changed.
  bool adopt(const Subscription& next, bool resubscribe, bool announce);
  void subscribe();
  void check_give_up();

  const RenderOptions& o_;
  std::ostream& log_;
  const std::atomic<bool>& interrupted_;
  const CurveClientKeys curve_;
  const std::chrono::milliseconds request_timeout_, frame_timeout_;
  std::unique_ptr<CommandClient> cmd_;
  std::vector<std::uint32_t> created_;  // --create: the instances made, made again after a restart
  Subscription sub_;
  ClientBasis basis_;  // sizes, scene and hash only, once on the GPU
  std::unique_ptr<RenderTarget> target_;
  std::unique_ptr<FrameSubscriber> subscriber_;
  SequenceTracker sequence_;                    // of the first followed instance
  std::map<std::uint32_t, FrameState> latest_;  // each followed instance's last frame
  State state_ = State::following;
  std::uint64_t reconnects_ = 0, rendered_ = 0, rejected_ = 0, rejected_run_ = 0, malformed_ = 0;
  bool restart_explained_ = false;  // a reconnect was checked; the step back of seq it brings needs no check
  std::chrono::steady_clock::time_point last_rendered_, last_received_, last_recheck_;
  std::string stalled_;  // why nothing is rendered, for the give-up message; "" while frames are drawn
};

}  // namespace phasecast::client
